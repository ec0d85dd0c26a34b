"""``rivercal bench online --mode``: the modes it times, and a mode or ensemble size it cannot time refused by name."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from rivercal.bench.online import bench_online
from rivercal.cli.main import app


@pytest.mark.parametrize(("args", "named"), [(["--mode", "states"], "--mode"), (["--mode", "both", "--members", "1"],
                                                                                 "--members")])
def test_a_mode_or_ensemble_size_it_cannot_time_exits_2_and_names_the_option(args, named):
    result = CliRunner().invoke(app, ["bench", "online", *args])
    assert result.exit_code == 2, result.output
    assert named in result.output
    assert "Traceback" not in result.output and "internal error" not in result.output


def test_the_library_call_refuses_another_mode_before_any_run():
    with pytest.raises(ValueError, match="parameters or both, got 'states'"):
        bench_online(mode="states")

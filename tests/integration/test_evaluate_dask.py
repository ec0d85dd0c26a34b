"""Evaluation on a Dask cluster: a LocalCluster of two worker processes on this machine, never a mock.

The reference of every result is the same evaluation in this process (serial): a cluster changes where a
run happens, never what it returns, including the failure policy, budgets and deadlines.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.errors import EngineDivergedError
from rivercal.evaluate import ClusterError, DaskCluster, Evaluator, Tasks
from rivercal.optimise.result import STATUS_DEADLINE, STATUS_MAX_NFEV
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from tests import dask_helpers
from tests.processes import descendants, kill_left, survivors

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def cluster():
    with DaskCluster("local:2") as c:
        yield c


@pytest.fixture(scope="module")
def problem():
    """FA and Wc of the default case over two days, twin observations of FA=20, Wc=0.6."""
    from rivercal.model import load_model
    from rivercal.twin.truth import twin_truth

    model = load_model("dommel")
    known = {p.name: p for p in model.case.spec.parameters}
    params = ParameterSet([known["FA"], known["Wc"]])
    window = (pd.Timestamp("2010-09-27", tz="UTC"), pd.Timestamp("2010-09-29", tz="UTC"))
    truth = twin_truth(model, params.quantities({"FA": 20.0, "Wc": 0.6}), window)
    p = CalibrationProblem(model, params, truth.observations, window, state=truth.state)
    p.sqrt_weights  # noqa: B018 - computed once, before the problem is sent
    return p


def test_results_come_back_in_order_and_equal_the_serial_runs(cluster, problem) -> None:
    xs = [problem.x0 + np.array([0.4 * i, 0.01 * i]) for i in range(5)]
    serial = [problem.residuals(x) for x in xs]
    with Evaluator(problem.residuals, workers=cluster) as batch:
        assert batch.workers == 2
        on_cluster = batch(xs)
        streamed = dict(batch.as_completed(xs))
    for a, b in zip(on_cluster, serial, strict=True):
        np.testing.assert_array_equal(a, b)
    assert sorted(streamed) == list(range(5))
    for i, r in streamed.items():
        np.testing.assert_array_equal(r, serial[i])


def test_the_function_goes_to_each_worker_once_not_once_per_evaluation(cluster) -> None:
    model = dask_helpers.Counted("once")
    with Evaluator(dask_helpers.Scaled(model, 2.0), workers=cluster) as batch:
        for _ in range(3):
            out = batch([np.array([float(i)]) for i in range(10)])
            assert [float(r[0]) for r in out] == [2.0 * i for i in range(10)]
        per_worker = cluster.client.run(dask_helpers.loads, "once")
    assert max(per_worker.values()) == 1, per_worker
    assert sum(per_worker.values()) >= 1


def test_a_shared_model_is_sent_once_for_every_problem_built_on_it(cluster) -> None:
    model = dask_helpers.Counted("shared", size=100_000)
    cluster.share(model)
    for factor in (2.0, 3.0, 5.0):  # e.g. the problems of three on-line cycles
        with Evaluator(dask_helpers.Scaled(model, factor), workers=cluster) as batch:
            out = batch([np.array([1.0]), np.array([2.0]), np.array([3.0]), np.array([4.0])])
        assert [float(r[0]) for r in out] == [factor, 2 * factor, 3 * factor, 4 * factor]
    per_worker = cluster.client.run(dask_helpers.loads, "shared")
    assert max(per_worker.values()) == 1, per_worker  # three problems, one copy of the model per worker


def _strict_problem(on_failure: str) -> CalibrationProblem:
    """Global friction of the synthetic case under a velocity limit (0.5 m/s) that every run breaks."""
    import tomllib

    from rivercal.case import case_from_dict
    from rivercal.case.load import resolve_case_path
    from rivercal.model import build_model
    from rivercal.observations import ObservationSeries, ObservationSet
    from rivercal.parameters import Parameter

    root = resolve_case_path("synthetic")
    data = tomllib.loads((root / "case.toml").read_text(encoding="utf-8"))
    normal = build_model(case_from_dict(data, root))
    start = normal.start + pd.Timedelta(hours=6)
    _, state = normal.simulate(None, end=start - pd.Timedelta(hours=1))
    data["engine"]["max_velocity"] = 0.5
    strict = build_model(case_from_dict(data, root))
    window = (start, start + pd.Timedelta(hours=3))
    times = pd.date_range(*window, freq="h")
    obs = ObservationSet((ObservationSeries.from_series(pd.Series(np.full(times.size, 11.0), index=times),
                                                        id="S1.h_up", sigma=0.05),))
    param = Parameter(name="F", targets=["friction:global"], initial=25.0, min=10.0, max=60.0, perturbation=2.0)
    return CalibrationProblem(strict, ParameterSet([param]), obs, window, warmup="1h", state=state,
                              on_failure=on_failure, penalty=1e6)


def test_the_failure_policy_holds_on_the_cluster(cluster) -> None:
    xs = [np.array([20.0]), np.array([30.0])]
    penalty = _strict_problem("penalty")
    serial = [penalty.residuals(x) for x in xs]
    assert [float(r @ r) for r in serial] == pytest.approx([1e6, 1e6])  # the failed runs got the penalty cost
    with Evaluator(penalty.residuals, workers=cluster) as batch:
        for a, b in zip(batch(xs), serial, strict=True):
            np.testing.assert_array_equal(a, b)
    strict = _strict_problem("raise")
    with pytest.raises(EngineDivergedError) as serial_error:
        strict.residuals(xs[0])
    with Evaluator(strict.residuals, workers=cluster) as batch, pytest.raises(EngineDivergedError) as info:
        batch(xs)
    assert str(info.value) == str(serial_error.value)  # the worker's error, unchanged: time, place, value


def test_budget_and_deadline_stop_a_calibration_on_the_cluster(cluster, problem) -> None:
    serial = calibrate(problem, "dud", workers=1, max_nfev=4)
    on_cluster = calibrate(problem, "dud", workers=cluster, max_nfev=4)
    assert on_cluster.result.nfev == 4 and on_cluster.result.status == STATUS_MAX_NFEV
    np.testing.assert_array_equal(on_cluster.result.x, serial.result.x)
    late = calibrate(problem, "dud", workers=cluster, deadline=1e-6)
    assert late.result.status == STATUS_DEADLINE and late.result.aborted
    assert late.result.nfev == 1   # past its deadline before it began: the start point alone
    assert [x.tolist() for x, _ in late.result.evaluations] == [problem.x0.tolist()]


def test_no_run_starts_on_the_cluster_after_the_deadline(cluster, tmp_path) -> None:
    """Twelve one-second runs on two workers take six seconds; with a deadline after 1.5 s none starts later."""
    xs = [np.array([float(i)]) for i in range(12)]
    fun = dask_helpers.Logged(tmp_path / "starts.txt", 1.0)
    with Evaluator(fun, workers=cluster) as batch:
        deadline = time.monotonic() + 1.5
        out = batch.within(xs, deadline, keep=7)
        returned = time.monotonic()
        after = batch(xs[:3])  # the workers take new work
    done = [i for i, r in enumerate(out) if r is not None]
    assert 7 in done and 2 <= len(done) < len(xs)
    for i in done:
        np.testing.assert_array_equal(out[i], xs[i] ** 2)
    assert returned < deadline + 0.5   # it stopped waiting at the deadline
    started = [t for t in fun.starts() if t < returned]
    assert all(t < deadline + 0.5 for t in started), [t - deadline for t in started]
    assert len(started) <= len(done) + cluster.n_workers   # at most one run per worker dropped, none queued
    np.testing.assert_array_equal(np.concatenate(after), [0.0, 1.0, 4.0])


def test_the_workers_of_a_local_cluster_run_without_dasks_profiler(cluster) -> None:
    """Its sampling thread would take about 5 % of a core from each worker's model runs."""
    import dask

    enabled = cluster.client.run(lambda: dask.config.get("distributed.worker.profile.enabled"))
    assert len(enabled) == 2 and not any(enabled.values()), enabled
    assert dask.config.get("distributed.worker.profile.enabled")  # this process's own setting is left as it was


def _started(obj: object, path: Path, x: float) -> float:
    return dask_helpers.started(path, x, 0.5)  # long enough that the pairs start in turn on a busy machine


def test_tasks_submitted_at_once_start_in_their_order_and_give_their_results(cluster, tmp_path) -> None:
    """A batch goes to the scheduler as one graph; its tasks still start in the order given (the scenarios of a
    suite go likely-longest first), two at a time on the two workers, and each result is its own."""
    log = tmp_path / "starts.txt"
    items = [float(i) for i in range(8)]
    with Tasks(None, cluster) as tasks:
        futures = tasks.submit_all(_started, [(log, x) for x in items])
        assert [f.result() for f in futures] == items
    starts = sorted((float(t), float(x)) for x, t in (line.split() for line in log.read_text().splitlines()))
    order = [x for _, x in starts]
    assert sorted(order) == items
    assert [int(x) // 2 for x in order] == [i // 2 for i in range(8)], order


def test_twin_scenarios_on_the_cluster_equal_the_serial_ones(cluster) -> None:
    from rivercal.model import load_model
    from rivercal.twin.suites import run_scenarios, suite_scenarios

    model = load_model("dommel")
    scenarios = suite_scenarios("F1W0", ids=["H1", "L2"], window="2010-09-27/2010-09-28")
    serial = run_scenarios(model, scenarios, workers=1)
    seen = []
    on_cluster = run_scenarios(model, scenarios, workers=cluster, progress=seen.append)
    assert sorted(r.id for r in seen) == ["H1", "L2"]
    for a, b in zip(on_cluster, serial, strict=True):
        assert (a.id, a.model_runs) == (b.id, b.model_runs)
        assert a.estimates == b.estimates


def test_a_lost_worker_evaluations_run_again_elsewhere(cluster, tmp_path) -> None:
    marker = tmp_path / "killed"
    with Evaluator(dask_helpers.KillOnce(marker), workers=cluster) as batch:
        out = batch([np.array([float(i)]) for i in range(8)])
    assert marker.exists()  # a worker died in the middle of an evaluation
    assert [float(r[0]) for r in out] == [2.0 * i for i in range(8)]
    deadline = time.monotonic() + 60
    while cluster.n_workers < 2 and time.monotonic() < deadline:  # the nanny restarts it
        time.sleep(0.2)
    assert cluster.n_workers == 2


def test_bad_addresses_and_unsuitable_clusters_are_refused() -> None:
    with pytest.raises(ValueError, match="local:N"):
        DaskCluster("localhost:8786")
    with pytest.raises(ClusterError, match=r"cannot reach the Dask scheduler at tcp://127\.0\.0\.1:9"):
        DaskCluster("tcp://127.0.0.1:9", timeout_s=1.0)
    import distributed

    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address="127.0.0.1:0") as lc, \
            pytest.raises(ClusterError, match="--nthreads 1"):
        DaskCluster(lc.scheduler_address)


# -- the workers of a local:N cluster end with their parent ---------------------------------------------------


def parent() -> None:
    with DaskCluster("local:2") as c, Evaluator(np.square, workers=c) as batch:
        batch([np.array([1.0]), np.array([2.0])])
        print("ready", flush=True)
        time.sleep(600)


def busy_parent(folder: Path) -> None:
    """A parent whose two workers are each in a long compiled call (holding their interpreter lock)."""
    with DaskCluster("local:2") as c, Tasks(None, c) as pool:
        pool.map(_square, [1.0, 2.0])
        marks = [folder / f"started-{i}" for i in range(2)]
        futures = [pool.submit(_hold, 1e12, mark) for mark in marks]
        deadline = time.monotonic() + 120
        while not all(m.exists() for m in marks) and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.3)  # both calls have started: each worker is in its long compiled call
        print("ready", flush=True)
        for f in futures:
            f.result()


def _square(obj: object, x: float) -> float:
    return x * x


def _hold(obj: object, additions: float, started: Path) -> float:
    return dask_helpers.hold_interpreter(additions, started)


@pytest.mark.parametrize(("role", "how"), [("parent", signal.SIGKILL), ("parent", signal.SIGTERM),
                                           ("busy_parent", signal.SIGTERM)])
def test_the_workers_of_a_local_cluster_end_when_its_parent_is_killed(role: str, how: signal.Signals,
                                                                     tmp_path: Path) -> None:
    """Idle or in the middle of a long task that keeps a worker's interpreter lock, the workers go at once."""
    proc = subprocess.Popen([sys.executable, "-m", "tests.integration.test_evaluate_dask", role, str(tmp_path)],
                            cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line.strip() == "ready", proc.stderr.read()[-2000:]
        workers = sorted(descendants(proc.pid))
        assert len(workers) >= 2, workers
    finally:
        os.kill(proc.pid, how)
        proc.wait(timeout=30)
        proc.stdout.close()
        proc.stderr.close()
    try:
        assert survivors(workers, within_s=10.0) == []
    finally:
        kill_left(workers)



@pytest.mark.slow
def test_the_command_line_runs_on_a_dask_cluster_quietly_and_checks_the_address(tmp_path: Path) -> None:
    """On a cluster the calibration equals the serial one. Dask logs its cluster's start at INFO; the command
    line shows warnings only, as for rivercal's own log, and Dask's INFO with --verbose.

    One worker process each (every worker pays the start of a Python process with rivercal's numerical stack,
    about 2 s of processor time): what two workers change (order, one copy of the function per worker, the
    same results as the serial runs) is proved on this module's two-worker cluster above."""
    import json

    from typer.testing import CliRunner

    from rivercal.cli.main import app

    runner = CliRunner()
    base = ["calibrate", "dommel", "--params", "FA", "--window", "2010-09-27/2010-09-28", "--twin", "FA=20",
            "--json"]
    serial = runner.invoke(app, [*base, "--workers", "1", "--out", str(tmp_path / "a")])
    assert serial.exit_code == 0, serial.output
    cli = [sys.executable, "-m", "rivercal.cli"]
    quiet = subprocess.run([*cli, *base, "--dask", "local:1", "--out", str(tmp_path / "b")], cwd=ROOT,
                           capture_output=True, text=True, timeout=600, check=False)
    assert quiet.returncode == 0, quiet.stderr[-2000:]
    assert not [line for line in quiet.stderr.splitlines() if line.startswith(("INFO", "DEBUG"))], quiet.stderr[-2000:]
    a, b = json.loads(serial.stdout.splitlines()[-1]), json.loads(quiet.stdout.splitlines()[-1])
    assert a["estimates"] == b["estimates"] and a["model_runs"] == b["model_runs"]
    # the log is the point here, not the calibration: two model runs are enough
    verbose = subprocess.run([*cli, "--verbose", *base, "--max-nfev", "2", "--dask", "local:1", "--out",
                              str(tmp_path / "c")], cwd=ROOT, capture_output=True, text=True, timeout=600, check=False)
    assert verbose.returncode == 0, verbose.stderr[-2000:]
    assert "INFO distributed.scheduler" in verbose.stderr
    for args, text in ((["--dask", "localhost"], "local:N"), (["--dask", "local:2", "--workers", "2"], "not both")):
        bad = runner.invoke(app, [*base, *args, "--out", str(tmp_path / "d")])
        assert bad.exit_code == 2 and "--dask" in bad.output and text in bad.output, bad.output


if __name__ == "__main__":
    if sys.argv[1] == "busy_parent":
        busy_parent(Path(sys.argv[2]))
    else:
        parent()

"""An estimate that jumps without a transition is accepted with its reason, and the run's end says so; the
report lists the coverage of every series behind a data alert.

On the toy river of :mod:`tests.unit.test_online_service` (friction 16 → 25 on 2010-11-01, then a crest
raised by 0.2 m on 2010-11-04), the service follows the friction's transition when the crest's estimate
jumps: one change is followed at a time, so the crest's jump is accepted without a transition search,
raises no alert (a jump alone is no intervention) and stores why. The run's end in words (the terminal,
the report and the JSON print it) names the last accepted value, the cycle that accepted it, that reason
and the forecast issued.
"""

from __future__ import annotations

import pandas as pd

from rivercal.online.service import OnlineConfig
from rivercal.report.online_figures import final_state_lines
from tests.unit.test_online_service import MOWED, ToyRiver, _observations, _service


def test_a_jump_while_a_change_is_followed_is_accepted_with_its_reason_and_the_end_says_so(tmp_path) -> None:
    raised = [*MOWED, (pd.Timestamp("2010-11-04", tz="UTC"), {"weir:W.crest_level": 10.2})]
    config = OnlineConfig(parameters=("FA", "Wd"), workers=1, deadline_s=None)
    store, svc = _service(tmp_path, config, _observations(ToyRiver(), raised), first="2010-10-31")
    with store:
        out = svc.replay("2010-11-08")
        # the crest's change is seen once the week-long window holds enough of it: its estimate jumps
        jumped = next(o for o in out if "Wd" not in o.held and abs(o.accepted["Wd"] - 10.0) > 0.1)
        before = out[out.index(jumped) - 1].accepted["Wd"]
        assert jumped.transition is not None and jumped.transition.parameter == "FA"  # FA's change is followed
        assert (store.alerts(svc.run)["kind"] == "jump").sum() == 1  # FA's, not Wd's
        est = store.estimates(svc.run)
        row = est[(est["cycle"] == jumped.cycle) & (est["parameter"] == "Wd")].iloc[0]
        assert bool(row["accepted"]) and "while the change of FA is followed" in row["reason"]
        assert f"last accepted {before:.4g}" in row["reason"]
        last = out[-1]
        lines = final_state_lines(store, svc.run)
        # the dashboard's "Now" page gives the reason beside the accepted value (the jump is the latest cycle's)
        from rivercal.dashboard.views import now_view

        rows = {r["parameter"]: r for r in now_view(store, svc.run)["estimates"]}
        assert rows["Wd"]["state"] == "accepted"
        assert last.cycle == jumped.cycle and "while the change of FA is followed" in rows["Wd"]["why"]
        wd = est[(est["parameter"] == "Wd") & est["accepted"].astype(bool)].iloc[-1]
    assert lines[0].startswith(f"At the end of the run, cycle {last.cycle} (2010-11-08 00:00) issued ")
    assert ("rivercal's forecast" if last.issued == "updated" else "the DSS's forecast") in lines[0]
    line = next(x for x in lines if x.startswith("Wd: "))
    shown = f"{last.accepted['Wd']:.4f}"  # as the terminal's table of estimates prints a level
    assert f"last accepted {shown} m AD, by cycle {int(wd['cycle'])} — jumped" in line


def test_the_report_lists_the_coverage_of_every_series_behind_a_data_alert(tmp_path) -> None:
    from rivercal.report.online import _data_coverage

    config = OnlineConfig(parameters=("FA",), workers=1, deadline_s=None)
    gap = ("2010-10-29 01:00", "2010-10-31 00:00")  # 48 of the window's 169 hourly values of both gauges missing
    store, svc = _service(tmp_path, config, _observations(ToyRiver(), MOWED, drop=gap), first="2010-10-31")
    with store:
        svc.replay("2010-10-31")
        alerts = store.alerts(svc.run)
        assert list(alerts["kind"]) == ["data"] and "A.h (72%), B.h (72%)" in alerts["message"].iloc[0]
        table = _data_coverage(store, svc.run, store.cycles(svc.run), alerts, svc.model)
    assert list(table["series"]) == ["A.h", "B.h"] and set(table["cycle"]) == {0}
    assert (table["expected"] == 169).all() and (table["values"] == 121).all()
    assert table["coverage"].tolist() == [round(121 / 169, 4)] * 2


def test_the_runs_end_shows_no_unit_after_a_dimensionless_value(tmp_path) -> None:
    # an imported SOBEK 3 model's friction factor F_scale has unit "-": "1.20, by cycle 0", not "1.20 -, by cycle 0"
    from rivercal.store import CycleRecord, EstimateRecord, Schedule, Store

    schedule = Schedule("2001-01-20T00:00:00Z", period=pd.Timedelta(days=1), window=pd.Timedelta(days=2))
    with Store(tmp_path / "s.db") as store:
        run = store.ensure_run("r", "test_compound", {})
        spec = store.begin_cycle(run.id, store.next_cycle(run.id, schedule))
        store.commit_cycle(run.id, CycleRecord(0, spec.window_start, spec.window_end, spec.issue_time, estimates=[
            EstimateRecord("F_scale", 1.2, "-", 0.01, True),
            EstimateRecord("W_1", 0.123456, "m AD", 0.01, True)]))
        lines = final_state_lines(store, run)
    assert "F_scale: last accepted 1.20, by cycle 0." in lines
    assert "W_1: last accepted 0.1235 m AD, by cycle 0." in lines

"""greybox.fleet on a small synthetic fleet (scripts/fleet_logs.py: 4 motors × 4 logs, motor
1 demagnetises and motor 2 gets an R_s fault from the 4th log): the flags find exactly those
logs, and the inferred temperatures are within a stated tolerance of the truth."""

from __future__ import annotations

import csv
import importlib.util

import pyarrow as pa
import pytest

import greybox
import greybox.fleet

from conftest import ROOT

MOTOR = r"(motor\d+)_log"
#: Inferred winding and magnet temperatures against the truth [K], the references taken
#: from each motor's first 3 logs (whose measured temperatures are off by σ = 1 K each).
TOL_REFERENCED = 1.5
#: The same with each motor's true R_s0 and psi_f0 given (the fit's own error only).
TOL_GIVEN = 0.2


def _generator():
    spec = importlib.util.spec_from_file_location("fleet_logs", ROOT / "scripts" / "fleet_logs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """The logs' folder, the summary of fit_many and the truth rows (dicts)."""
    out = tmp_path_factory.mktemp("fleet")
    _generator().main([str(out), "--motors", "4", "--logs", "4", "--demagnetised", "1", "--fault", "2"])
    summary = greybox.fit_many(out, pole_pairs=4)
    with open(out / "truth.tsv", newline="") as f:
        truth = list(csv.DictReader(f, delimiter="\t"))
    assert summary.column("status").to_pylist() == ["ok"] * 16
    return out, summary, truth


def _flagged(view, flag):
    return [
        log.rsplit("/", 1)[-1] for log, f in zip(view.column("log").to_pylist(), view.column(flag).to_pylist()) if f
    ]


def test_flags_find_the_faulty_motors_and_no_other(fleet):
    _, summary, truth = fleet
    view = greybox.fleet.fleet_view(summary, motor_id=MOTOR, t0=20, temperature="t_winding", magnet_offset=15)
    assert view.column("motor").to_pylist()[::4] == ["motor000", "motor001", "motor002", "motor003"]
    assert _flagged(view, "demagnetised") == [t["path"] for t in truth if t["demagnetised"] == "True"]
    assert _flagged(view, "r_s_excess") == [t["path"] for t in truth if t["r_s_fault"] == "True"]
    assert _flagged(view, "demagnetised") == ["motor001_log03.parquet"]
    assert _flagged(view, "r_s_excess") == ["motor002_log03.parquet"]
    motors = greybox.fleet.by_motor(view)
    assert motors.column("demagnetised").to_pylist() == [False, True, False, False]
    assert motors.column("r_s_excess").to_pylist() == [False, False, True, False]


def _temperature_errors(view, truth):
    """The largest |inferred − true| winding temperature over the logs without an R_s fault,
    and magnet temperature over those not demagnetised [K]."""
    tw = view.column("t_winding [°C]").to_pylist()
    tm = view.column("t_magnet [°C]").to_pylist()
    dw = max(abs(a - float(t["t_winding"])) for a, t in zip(tw, truth) if t["r_s_fault"] == "False")
    dm = max(abs(a - float(t["t_magnet"])) for a, t in zip(tm, truth) if t["demagnetised"] == "False")
    return dw, dm


def test_inferred_temperatures(fleet):
    _, summary, truth = fleet
    view = greybox.fleet.fleet_view(summary, motor_id=MOTOR, t0=20, temperature="t_winding", magnet_offset=15)
    dw, dm = _temperature_errors(view, truth)
    assert dw < TOL_REFERENCED and dm < TOL_REFERENCED, (dw, dm)

    r_s0 = {t["motor"]: float(t["r_s0"]) for t in truth}
    psi_f0 = {t["motor"]: float(t["psi_f0"]) for t in truth}
    given = greybox.fleet.fleet_view(
        summary, motor_id=MOTOR, t0=20, r_s0=r_s0, psi_f0=psi_f0, temperature="t_winding", magnet_offset=15
    )
    dw, dm = _temperature_errors(given, truth)
    assert dw < TOL_GIVEN and dm < TOL_GIVEN, (dw, dm)
    assert _flagged(given, "demagnetised") == ["motor001_log03.parquet"]
    assert _flagged(given, "r_s_excess") == ["motor002_log03.parquet"]


def test_motor_column_and_temperature_table(fleet):
    """The motor id from a column and the temperatures from a table give the same view."""
    _, summary, truth = fleet
    by_path = greybox.fleet.fleet_view(summary, motor_id=MOTOR, temperature="t_winding", magnet_offset=15)
    temps = pa.table({"log": summary.column("log"), "temperature": by_path.column("temperature [°C]")})
    with_column = summary.append_column("unit", pa.array([t["motor"] for t in truth]))
    by_column = greybox.fleet.fleet_view(with_column, motor_id="unit", temperature=temps, magnet_offset=15)
    assert by_column.equals(by_path)


def test_bad_input_is_named(fleet):
    _, summary, _ = fleet
    with pytest.raises(greybox.OptionError, match="does not match the log '.*motor000_log00.parquet'"):
        greybox.fleet.fleet_view(summary, motor_id=r"(pump\d+)")
    with pytest.raises(greybox.OptionError, match="exactly one group"):
        greybox.fleet.fleet_view(summary, motor_id="motor")
    with pytest.raises(greybox.DataError, match="motor000_log00.parquet: cannot read column `t_stator`"):
        greybox.fleet.fleet_view(summary, motor_id=MOTOR, temperature="t_stator")
    with pytest.raises(greybox.OptionError, match="no value for the motor 'motor001'"):
        greybox.fleet.fleet_view(summary, motor_id=MOTOR, r_s0={"motor000": 1.2})
    with pytest.raises(greybox.DataError, match="no column `r_s"):
        greybox.fleet.fleet_view(summary.select(["log", "status"]), motor_id=MOTOR)


def test_view_of_the_command_lines_summary(fleet, cli, tmp_path):
    """``greybox fit --each DIR --summary S``, read with pyarrow.csv, gives the same view."""
    import subprocess

    import pyarrow.csv as pacsv

    out, summary, _ = fleet
    run = subprocess.run([str(cli), "fit", "--each", str(out), "-p", "4", "--summary", str(tmp_path / "s.csv")])
    assert run.returncode == 0
    from_cli = pacsv.read_csv(tmp_path / "s.csv")
    opts = dict(motor_id=MOTOR, temperature="t_winding", magnet_offset=15)
    assert greybox.fleet.fleet_view(from_cli, **opts).equals(greybox.fleet.fleet_view(summary, **opts))


def test_intervals_are_the_summarys(fleet):
    """The view's intervals are the summary's (the fits' reports'), not ± 1.96 standard
    errors; a summary without interval columns (written before they existed) falls back to
    those; a failed log has none."""
    _, summary, _ = fleet
    view = greybox.fleet.fleet_view(summary, motor_id=MOTOR)
    for name, unit in (("r_s", "Ω"), ("k_e", "V s/rad")):
        for end in ("low", "high"):
            assert view.column(f"{name}_{end} [{unit}]").equals(summary.column(f"{name}_{end} [{unit}]"))
    # The summary's own interval (Student's t at the fit's degrees of freedom) is wider than
    # ± 1.96 se: the view took it.
    r_s, se = summary.column("r_s [Ω]").to_pylist(), summary.column("r_s_se [Ω]").to_pylist()
    high = view.column("r_s_high [Ω]").to_pylist()
    assert all(h > v + greybox.fleet.Z95 * s for h, v, s in zip(high, r_s, se))
    old = summary.drop_columns([c for c in summary.column_names if c.split(" [")[0].endswith(("_low", "_high"))])
    old_view = greybox.fleet.fleet_view(old, motor_id=MOTOR)
    assert old_view.column("r_s_high [Ω]").to_pylist() == [v + greybox.fleet.Z95 * s for v, s in zip(r_s, se)]
    failed = summary.set_column(
        summary.column_names.index("status"), "status", pa.array(["failed"] + ["ok"] * (len(r_s) - 1))
    )
    assert greybox.fleet.fleet_view(failed, motor_id=MOTOR).column("k_e_low [V s/rad]")[0].as_py() is None
    # A missing end (an infinite one is written empty) stays missing: never ± 1.96 se.
    k = summary.column_names.index("k_e_high [V s/rad]")
    highs = pa.array([None] + summary.column(k).to_pylist()[1:], pa.float64())
    open_end = summary.set_column(k, "k_e_high [V s/rad]", highs)
    one = greybox.fleet.fleet_view(open_end, motor_id=MOTOR)
    assert one.column("k_e_high [V s/rad]")[0].as_py() is None
    assert one.column("k_e_low [V s/rad]")[0].as_py() == summary.column("k_e_low [V s/rad]")[0].as_py()

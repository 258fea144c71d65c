"""greybox.fit_many: one row per log with the columns of --summary, failures as rows."""

from __future__ import annotations

import csv
import shutil
import subprocess
import time

import pyarrow as pa
import pytest

import greybox


@pytest.fixture
def logs(sample, tmp_path):
    """Three copies of the sample log (named a, b, c) and a broken log."""
    paths = []
    for name in ("a", "b", "c"):
        p = tmp_path / f"{name}.csv.gz"
        shutil.copy(sample, p)
        paths.append(p)
    bad = tmp_path / "d.csv"
    bad.write_text("t,ud,uq,id,iq\n0,1,2,3,4\n")
    return paths + [bad]


def test_rows_and_failed_log(logs):
    table = greybox.fit_many(logs, pole_pairs=4)
    assert table.num_rows == 4
    assert table.column("name").to_pylist() == ["a", "b", "c", "d"]
    assert table.column("status").to_pylist() == ["ok", "ok", "ok", "failed"]
    errors = table.column("error").to_pylist()
    assert errors[:3] == [None, None, None] and "missing column" in errors[3]
    assert table.schema.field("pole_pairs").type == pa.int64()
    assert table.schema.field("converged").type == pa.bool_()
    values = table.column("r_s [Ω]").to_pylist()
    assert values[0] == values[1] == values[2] and values[3] is None


def test_missing_file_is_a_row(sample, tmp_path):
    table = greybox.fit_many([sample, tmp_path / "gone.csv"], pole_pairs=4)
    assert table.column("status").to_pylist() == ["ok", "failed"]
    assert "cannot read" in table.column("error").to_pylist()[1]


def test_columns_equal_the_cli_summary(logs, cli, tmp_path):
    folder = logs[0].parent
    out = tmp_path / "summary"
    subprocess.run([str(cli), "fit", "--each", str(folder), "-p", "4", "--summary", str(out), "-q"], capture_output=True)
    with open(f"{out}.csv", newline="") as f:
        rows = list(csv.reader(f))
    table = greybox.fit_many(str(folder), pole_pairs=4)
    assert table.column_names == rows[0]
    for k, row in enumerate(rows[1:]):
        for name, cell in zip(rows[0], row):
            if name == "time [s]":
                continue
            got = table.column(name)[k].as_py()
            if got is None:
                assert cell == ""
            elif isinstance(got, float):
                assert got == float(cell), name
            else:
                assert str(got).lower() == cell.lower(), name


def test_options_checked_before_any_log(logs):
    with pytest.raises(greybox.OptionError, match='method="ls"'):
        greybox.fit_many(logs, pole_pairs=4, method="ls")
    with pytest.raises(greybox.OptionError, match="--each"):
        greybox.fit_many("/no/such/folder/*.csv", pole_pairs=4)


def test_threads_against_a_loop(logs, capsys):
    """fit_many's threads against a Python loop of fit (timings printed, not asserted)."""
    good = logs[:3] * 2
    t0 = time.perf_counter()
    for p in good:
        greybox.fit(p, pole_pairs=4)
    loop = time.perf_counter() - t0
    t0 = time.perf_counter()
    table = greybox.fit_many(good, pole_pairs=4)
    many = time.perf_counter() - t0
    assert table.num_rows == len(good)
    with capsys.disabled():
        print(f"\n{len(good)} logs: loop of fit {loop:.3f} s, fit_many {many:.3f} s")


def test_shared_logs_threads_against_a_loop(shared, capsys):
    """fit_many on the development logs against a loop of fit (timings printed, not asserted)."""
    paths = sorted(shared.glob("servo_spm_*.csv.gz"))
    t0 = time.perf_counter()
    loop = [greybox.fit(p, pole_pairs=4).value("r_s") for p in paths]
    t_loop = time.perf_counter() - t0
    t0 = time.perf_counter()
    table = greybox.fit_many(paths, pole_pairs=4)
    t_many = time.perf_counter() - t0
    assert table.column("r_s [Ω]").to_pylist() == loop
    with capsys.disabled():
        print(f"\n{len(paths)} shared logs: loop of fit {t_loop:.2f} s, fit_many {t_many:.2f} s")

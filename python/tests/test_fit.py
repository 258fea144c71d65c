"""greybox.fit: paths and tables in, the report out, equal to the command line's."""

from __future__ import annotations

import json
import threading
import time

import pyarrow as pa
import pyarrow.csv as pacsv
import pytest

import greybox
from conftest import cli_json


def _without_timing(text: str) -> dict:
    report = json.loads(text)
    report.pop("timing", None)
    return report


def test_fit_sample(sample):
    fit = greybox.fit(sample, pole_pairs=4)
    assert fit.trusted
    params = fit.parameters
    assert params.column_names[:6] == ["name", "value", "unit", "std_error", "ci95_low", "ci95_high"]
    assert params.column("name").to_pylist() == ["r_s", "l_s", "k_e"]
    assert fit.value("r_s") == pytest.approx(0.9, rel=1e-4)
    assert fit.value("k_t") == pytest.approx(0.66, rel=1e-4)
    assert "k_t" in fit.derived.column("name").to_pylist()
    assert isinstance(fit.warnings, list)
    assert fit.to_dict() == json.loads(fit.to_json())
    assert "r_s" in str(fit)
    with pytest.raises(KeyError):
        fit.value("x_s")


def test_keys_and_bits_equal_the_cli(sample, cli):
    fit = greybox.fit(sample, pole_pairs=4)
    expected = cli_json(cli, str(sample), "-p", "4")
    assert list(fit.to_dict()) == list(json.loads(expected))
    assert _without_timing(fit.to_json()) == _without_timing(expected)


def test_options_mirror_the_cli(sample, cli):
    fit = greybox.fit(sample, pole_pairs=4, hold="stator", fix={"r_s": 0.9}, from_=0.2, max_iters=50)
    expected = cli_json(cli, str(sample), "-p", "4", "--hold", "stator", "--fix", "r_s=0.9", "--from", "0.2", "--max-iters", "50")
    assert _without_timing(fit.to_json()) == _without_timing(expected)
    assert fit.parameters.column("fixed").to_pylist()[0] is True


def test_least_squares_has_no_plot(sample):
    fit = greybox.fit(sample, pole_pairs=4, method="ls")
    assert fit.svg() is None
    assert fit.value("r_s") == pytest.approx(0.9, rel=1e-2)


def test_html_shows_table_and_plot(sample):
    html = greybox.fit(sample, pole_pairs=4)._repr_html_()
    assert "<pre>" in html and "r_s" in html and "<svg" in html


def _table(sample) -> pa.Table:
    import gzip

    with gzip.open(sample, "rb") as f:
        return pacsv.read_csv(f)


def test_pyarrow_table_equals_the_file(sample):
    table = _table(sample)
    from_file = greybox.fit(sample, pole_pairs=4)
    from_table = greybox.fit(table, pole_pairs=4, name="sample")
    a, b = _without_timing(from_file.to_json()), _without_timing(from_table.to_json())
    assert a["parameters"] == b["parameters"]
    assert b["experiments"] == ["sample"]


def test_polars_and_pandas(sample):
    pl = pytest.importorskip("polars")
    pd = pytest.importorskip("pandas")
    table = _table(sample)
    expected = greybox.fit(table, pole_pairs=4).parameters
    for frame in (pl.from_arrow(table), table.to_pandas(), pd.DataFrame(table.to_pydict())):
        got = greybox.fit(frame, pole_pairs=4).parameters
        assert got.column("value").to_pylist() == expected.column("value").to_pylist(), type(frame)


def test_joint_fit_of_a_list(sample):
    table = _table(sample)
    fit = greybox.fit([sample, table.slice(0, 10000)], pole_pairs=4)
    assert fit.to_dict()["experiments"] == ["sample", "table"]


def test_errors_are_typed_and_name_the_keyword(sample, tmp_path):
    with pytest.raises(greybox.OptionError, match="^dead_time='sometimes': expected none, estimate or a voltage"):
        greybox.fit(sample, pole_pairs=4, dead_time="sometimes")
    with pytest.raises(greybox.OptionError, match="^voltage='referense': expected actual or reference$"):
        greybox.fit(sample, pole_pairs=4, voltage="referense")
    with pytest.raises(greybox.OptionError, match="^u_dc='high': expected a number"):
        greybox.fit(sample, pole_pairs=4, u_dc="high")
    with pytest.raises(greybox.OptionError, match="unknown keyword `no_such_option`"):
        greybox.fit(sample, pole_pairs=4, no_such_option=1)
    with pytest.raises(greybox.OptionError, match="unknown keyword `dead_tme`: did you mean dead_time"):
        greybox.fit(sample, pole_pairs=4, dead_tme="estimate")
    with pytest.raises(greybox.OptionError, match='invalid option `dead_time`: .*voltage="reference"'):
        greybox.fit(sample, pole_pairs=4, dead_time="estimate")  # needs voltage="reference"
    with pytest.raises(greybox.OptionError, match="`json`"):
        greybox.fit(sample, pole_pairs=4, json="out.json")
    with pytest.raises(greybox.DataError, match="cannot read"):
        greybox.fit(tmp_path / "missing.csv", pole_pairs=4)
    bad = tmp_path / "bad.csv"
    bad.write_text("t,ud,uq,id\n0,1,2,3\n")
    with pytest.raises(greybox.DataError, match="missing column"):
        greybox.fit(bad, pole_pairs=4)
    with pytest.raises(greybox.DataError, match="missing column `w_m`"):
        greybox.fit(_table(sample).drop(["w_m"]), pole_pairs=4)
    with pytest.raises(greybox.DataError, match="not a log"):
        greybox.fit(42, pole_pairs=4)
    assert issubclass(greybox.DataError, greybox.Error) and issubclass(greybox.FitError, greybox.Error)


def test_untrusted_mirrors_exit_code_3(sample):
    fit = greybox.fit(sample, pole_pairs=4, max_iters=1)
    assert not fit.trusted
    assert greybox.fit(sample, pole_pairs=4, max_iters=1, allow_unconverged=True).trusted


def test_gil_released_during_fit(sample):
    """A Python thread keeps running while another thread fits."""
    ticks = []
    done = threading.Event()

    def tick():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=tick)
    t.start()
    try:
        start = time.perf_counter()
        greybox.fit(sample, pole_pairs=4, method="pem", voltage="reference", delay="estimate")
        end = time.perf_counter()
    finally:
        done.set()
        t.join()
    during = [x for x in ticks if start < x < end]
    # With the GIL held through the fit the ticker could not run at all.
    assert end - start < 0.01 or len(during) >= 3, (len(during), end - start)


SHARED = [
    ("servo_spm_moves", 4, "spm"),
    ("servo_spm_moves_idinj", 4, "spm"),
    ("servo_spm_moves_idinj_noisy", 4, "spm"),
    ("servo_spm_pwm_deadtime_idinj", 4, "spm"),
    ("servo_spm_pwm_deadtime_lowdrop", 4, "spm"),
    ("gem_spm_moves_idinj", 4, "spm"),
    ("ipm_moves_idinj", 2, "ipm"),
    ("ipm_pwm_deadtime_idinj", 2, "ipm"),
    ("gem_ipm_moves_idinj", 4, "ipm"),
    ("gem_ipm_moves_idinj_noisy", 4, "ipm"),
]


@pytest.mark.parametrize(
    "log,n_p,model,extra",
    [(f"{name}.csv.gz", n_p, model, []) for name, n_p, model in SHARED]
    + [("servo_spm_pwm_deadtime_idinj.csv.gz", 4, "spm", ["voltage=reference", "dead_time=estimate"])],
)
def test_shared_logs_equal_the_cli_to_the_bit(shared, cli, log, n_p, model, extra):
    options = dict(kv.split("=") for kv in extra)
    fit = greybox.fit(shared / log, pole_pairs=n_p, model=model, **options)
    flags = [w for kv in extra for w in ("--" + kv.split("=")[0].replace("_", "-"), kv.split("=")[1])]
    expected = cli_json(cli, str(shared / log), "-p", str(n_p), "--model", model, *flags)
    assert _without_timing(fit.to_json()) == _without_timing(expected)


def test_bad_table_values_name_the_table_and_row(sample):
    table = _table(sample)
    iq = table.column("iq").to_pylist()
    iq[5] = float("nan")
    bad = table.set_column(table.schema.get_field_index("iq"), "iq", pa.array(iq))
    with pytest.raises(greybox.DataError, match=r"run: .*`iq` is not finite at row 5"):
        greybox.fit(bad, pole_pairs=4, name="run")
    text = table.set_column(0, "t", pa.array([str(x) for x in table.column("t").to_pylist()]))
    with pytest.raises(greybox.DataError, match="column `t` holds"):
        greybox.fit(text, pole_pairs=4)


def test_fits_in_threads_equal_fits_in_a_loop(sample):
    from concurrent.futures import ThreadPoolExecutor

    options = [dict(hold="dq"), dict(hold="stator"), dict(to=1.5), dict(from_=0.8)]
    alone = [greybox.fit(sample, pole_pairs=4, **o).parameters for o in options]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(lambda o: greybox.fit(sample, pole_pairs=4, **o).parameters, options))
    assert all(a.equals(b) for a, b in zip(alone, threaded))


def test_record_batch_reader_and_split_gaps(sample):
    table = _table(sample)
    reader = pa.RecordBatchReader.from_batches(table.schema, table.to_batches(max_chunksize=3000))
    assert greybox.fit(reader, pole_pairs=4).parameters.equals(greybox.fit(table, pole_pairs=4).parameters)
    gap = pa.concat_tables([table.slice(0, 8000), table.slice(9000)])
    with pytest.raises(greybox.DataError, match="split-gaps"):
        greybox.fit(gap, pole_pairs=4)
    fit = greybox.fit(gap, pole_pairs=4, split_gaps=True, name="gap")
    assert fit.to_dict()["experiments"] == ["gap#1", "gap#2"]


def test_dir_lists_the_public_names_only():
    names = dir(greybox)
    assert "fit" in names and "__version__" in names
    for private in ("os", "json", "tempfile", "Any", "pa"):
        assert private not in names, private


def test_renamed_columns_are_named_in_one_message_then_fitted(sample):
    """A log with ``t, Id, Iq, Ud, Uq, speed_rpm``: one error names every renamed column as
    keywords; the keywords it gives fit the log in the next run."""
    import ast
    import math

    import pyarrow.compute as pc

    t = _table(sample)
    renamed = pa.table(
        {
            "t": t["t"],
            "Id": t["id"],
            "Iq": t["iq"],
            "Ud": t["ud"],
            "Uq": t["uq"],
            "speed_rpm": pc.multiply(t["w_m"], 60 / (2 * math.pi)),
        }
    )
    with pytest.raises(greybox.DataError) as e:
        greybox.fit(renamed, pole_pairs=4)
    message = str(e.value)
    for keyword in ('col_id="Id"', 'col_iq="Iq"', 'col_ud="Ud"', 'col_uq="Uq"', 'col_w="speed_rpm"', 'speed_unit="rpm"'):
        assert keyword in message, message
    columns_text, unit_text = message.split("or in one: ")[1].split(", speed_unit=")
    columns = ast.literal_eval(columns_text.removeprefix("columns="))
    assert columns == {"ud": "Ud", "uq": "Uq", "id": "Id", "iq": "Iq", "w_m": "speed_rpm"}
    fit = greybox.fit(renamed, pole_pairs=4, columns=columns, speed_unit=ast.literal_eval(unit_text))
    plain = greybox.fit(t, pole_pairs=4)
    for got, want in zip(fit.parameters["value"].to_pylist(), plain.parameters["value"].to_pylist()):
        assert got == pytest.approx(want, rel=1e-6)
    # The same with one keyword per column.
    each = greybox.fit(renamed, pole_pairs=4, col_id="Id", col_iq="Iq", col_ud="Ud", col_uq="Uq", col_w="speed_rpm", speed_unit="rpm")
    assert each.parameters["value"].to_pylist() == fit.parameters["value"].to_pylist()
    with pytest.raises(greybox.OptionError, match="^columns: not together with col_id"):
        greybox.fit(renamed, pole_pairs=4, columns=columns, col_id="Id")

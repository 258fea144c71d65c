"""greybox.dask.fit_fleet on a LocalCluster of two worker processes, against fit_many."""

from __future__ import annotations

import shutil
import sys

import pytest

import greybox

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as c:
            yield c


def _drop_time(table):
    return table.drop(["time [s]"])


def test_dask_is_imported_lazily():
    import subprocess

    out = subprocess.run(
        [sys.executable, "-c", "import sys, greybox; print('dask' in sys.modules)"], capture_output=True, text=True
    )
    assert out.stdout.strip() == "False", out.stderr


@pytest.mark.parametrize("group_size", [1, 2])
def test_fleet_equals_fit_many(client, sample, tmp_path, group_size):
    import greybox.dask

    paths = []
    for name in ("a", "b", "c"):
        p = tmp_path / f"{name}.csv.gz"
        shutil.copy(sample, p)
        paths.append(p)
    bad = tmp_path / "d.csv"
    bad.write_text("not a log\n")
    paths.append(bad)
    fleet = greybox.dask.fit_fleet(paths, client, pole_pairs=4, group_size=group_size)
    many = greybox.fit_many(paths, pole_pairs=4)
    assert _drop_time(fleet).equals(_drop_time(many))
    assert fleet.column("status").to_pylist() == ["ok", "ok", "ok", "failed"]


def test_fleet_without_a_client(sample, tmp_path):
    """client=None: the current client if there is one, else Dask's default scheduler."""
    import greybox.dask

    paths = [tmp_path / "a.csv.gz", tmp_path / "b.csv.gz"]
    for p in paths:
        shutil.copy(sample, p)
    fleet = greybox.dask.fit_fleet(paths, pole_pairs=4)
    assert _drop_time(fleet).equals(_drop_time(greybox.fit_many(paths, pole_pairs=4)))


def test_fleet_options_checked_once(client, sample):
    import greybox.dask

    with pytest.raises(greybox.OptionError, match="^dead_time='sometimes'"):
        greybox.dask.fit_fleet([sample], client, pole_pairs=4, dead_time="sometimes")

"""The Ray and Spark recipes (python/examples/) on a fleet of 6 logs, each checking its
result against fit_many to the bit. Skipped where Ray, PySpark or Java is not installed
(as in CI: they add 1.1 GB and 10–25 s of start-up; docs/python.md)."""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys

import pytest

from conftest import ROOT

EXAMPLES = ROOT / "python" / "examples"


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    out = tmp_path_factory.mktemp("fleet")
    args = [str(out), "--motors", "2", "--logs", "3", "--demagnetised", "-1", "--fault", "-1"]
    subprocess.run([sys.executable, str(ROOT / "scripts" / "fleet_logs.py"), *args], check=True)
    return out


def _needs(module: str) -> None:
    if importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} not installed (not part of CI: docs/python.md, Ray and Spark)")


def test_ray_recipe(logs):
    _needs("ray")
    run = subprocess.run([sys.executable, str(EXAMPLES / "ray_fleet.py"), str(logs)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "equal to fit_many: True" in run.stdout


def test_spark_recipe(logs):
    _needs("pyspark")
    if shutil.which("java") is None:
        pytest.skip("java not found (PySpark needs a Java 17 or 21 runtime)")
    run = subprocess.run([sys.executable, str(EXAMPLES / "spark_fleet.py"), str(logs)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "(equal to fit_many: True)" in run.stdout and "(estimates equal to fit_many: True)" in run.stdout

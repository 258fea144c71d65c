"""Shared fixtures: the repository's sample log, the development logs (skipped with one
reason when absent) and the command-line binary for bit-for-bit comparisons."""

from __future__ import annotations

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "data" / "sample.csv.gz"


def shared_dir() -> pathlib.Path:
    """``$GREYBOX_SHARED_DATA``, else ``../shared/data`` beside the repository (as the Rust
    tests find it)."""
    env = os.environ.get("GREYBOX_SHARED_DATA")
    return pathlib.Path(env) if env else ROOT.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared() -> pathlib.Path:
    """The development logs' folder; without it the test is skipped with one reason (shown
    once per test file by ``pytest -rs``)."""
    d = shared_dir()
    if not d.is_dir():
        pytest.skip(f"{d} not found (development logs are not part of the repository; set GREYBOX_SHARED_DATA)")
    return d


@pytest.fixture(scope="session")
def cli() -> pathlib.Path:
    """The command-line tool built by ``cargo build --release`` (or ``$GREYBOX_BIN``)."""
    binary = pathlib.Path(os.environ.get("GREYBOX_BIN", ROOT / "target" / "release" / "greybox"))
    if not binary.is_file():
        pytest.skip(f"{binary} not built (cargo build --release)")
    return binary


def cli_json(binary: pathlib.Path, *args: str) -> str:
    """The JSON report of ``greybox fit ARGS --json -`` (stdout), without its final newline."""
    out = subprocess.run([str(binary), "fit", *args, "--json", "-"], capture_output=True, text=True)
    assert out.returncode in (0, 3), out.stderr
    return out.stdout.rstrip("\n")


@pytest.fixture
def sample() -> pathlib.Path:
    """The 2-second log shipped in data/ (a servo with 4 pole pairs)."""
    return SAMPLE

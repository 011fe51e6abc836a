"""Shared helpers of the Python tests: the package (skip when not installed) and the CLI
binary the results are checked against (skip when not built)."""

import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def cli_path():
    p = os.environ.get("TILTING_BIN") or str(ROOT / "target" / "release" / "tilting")
    return p if os.path.exists(p) else None


@pytest.fixture(scope="session")
def cli():
    """Runs `tilting ARGS --json` and returns its stdout (text); skips without the binary."""
    path = cli_path()
    if path is None:
        pytest.skip("SKIP: the tilting binary is not built (cargo build --release -p tilting)")

    def run(*args):
        out = subprocess.run([path, *map(str, args)], capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        return out.stdout

    return run


def without(d, *keys):
    """A copy of the JSON object `d` without the keys (dotted paths): wall times."""
    d = json.loads(json.dumps(d))
    for k in keys:
        *head, last = k.split(".")
        cur = d
        for h in head:
            cur = cur[h]
        cur.pop(last)
    return d

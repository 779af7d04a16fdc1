import os
import shutil
import subprocess

import pytest


@pytest.fixture(scope="session")
def cli():
    """Runs the `stepdamp` CLI (STEPDAMP_BIN, else `stepdamp` on PATH); returns
    (returncode, stdout, stderr)."""
    exe = os.environ.get("STEPDAMP_BIN") or shutil.which("stepdamp")
    if not exe:
        pytest.fail("set STEPDAMP_BIN to the stepdamp CLI (python/ci.sh does)")

    def run(*args):
        p = subprocess.run([exe, "--quiet", *map(str, args)], capture_output=True, text=True)
        return p.returncode, p.stdout, p.stderr

    return run

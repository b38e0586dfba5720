"""The CLI binary the package is compared with: $RISKTWIN_BIN (tests/interop/python_package.rs
sets it to the build's `risktwin`)."""

import os
import subprocess

import pytest


@pytest.fixture(scope="session")
def risktwin_cli():
    binary = os.environ.get("RISKTWIN_BIN")
    if not binary:
        pytest.fail("RISKTWIN_BIN names the risktwin binary to compare with")

    def run(*args, cwd=None):
        out = subprocess.run([binary, *args], cwd=cwd, capture_output=True, text=True, timeout=600)
        assert out.returncode == 0, f"risktwin {args} failed:\n{out.stderr}"
        return out.stdout

    return run

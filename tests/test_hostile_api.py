"""No panic and no stray exception type across the boundary: the hostile-argument sweep of the
public API (tests/hostile_api.py) in a child process whose address space is bounded, and the
panic guard of the glue."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from crlam import _native
from crlam.errors import CrlamError, InternalError

#: Address space of the sweep's process: a regression that allocates without a limit check gets
#: a MemoryError (reported as a failure) instead of taking the machine.
SWEEP_ADDRESS_SPACE = 6 << 30


@pytest.mark.skipif(sys.platform != "linux", reason="bounds the child's address space with setrlimit (Linux)")
def test_every_entry_point_meets_hostile_arguments_with_crlam_errors_only() -> None:
    script = Path(__file__).with_name("hostile_api.py")
    done = subprocess.run([sys.executable, str(script), str(SWEEP_ADDRESS_SPACE)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["calls"] > 5000
    assert result["failures"] == [], "\n".join(result["failures"][:40])


def test_a_panic_in_the_core_reaches_python_as_an_internal_error() -> None:
    with pytest.raises(InternalError, match="internal error in _guarded_panic: boom") as info:
        _native._guarded_panic("boom")
    assert isinstance(info.value, CrlamError) and isinstance(info.value, Exception)
    # The map still works after a panic elsewhere (nothing is left poisoned).
    assert _native.CrmMap(0.2).cell_of(0.1, 0.1) == (0, 0)

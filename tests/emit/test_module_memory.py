"""The Python module's memory behaviour: no invalid read or write of the module's own code under
valgrind on a short run (single points, batches, strided views, results written into out=,
results let go of and filled anew, refused arguments), and a
batch of 10^7 states is computed right; one whose arguments cannot be copied is a MemoryError."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

SPECS = Path(__file__).resolve().parents[2] / "specs"


def test_valgrind_finds_nothing_in_the_module(build_module, tmp_path):
    if shutil.which("valgrind") is None:
        pytest.skip("valgrind is not installed (CI installs it)")
    module = build_module(SPECS / "two_link.yaml")
    script = tmp_path / "run.py"
    script.write_text(
        textwrap.dedent(f"""
        import sys
        import weakref
        sys.path.insert(0, {str(Path(module.__file__).parent)!r})
        import numpy as np
        import two_link as m
        rng = np.random.default_rng(0)
        q, qd = rng.normal(size=(50, 2)), rng.normal(size=(50, 2))
        for f in ("mass", "gravity", "jacobian", "fk"):
            getattr(m, f)(q), getattr(m, f)(q[0]), getattr(m, f)(q[::3])
        m.coriolis(q, qd), m.nonlinear(q.T.copy().T, qd), m.forward_dynamics(q, qd, qd)
        m.inverse_dynamics(q[::2], qd[::2], qd[::2]), m.servo_terms(q, qd)
        m.inverse_dynamics_derivatives(q, qd, qd), m.forward_dynamics_derivatives(q, qd, qd)
        m.discrete_dynamics_derivatives(q, qd, qd, 0.01), m.mass_inverse(q)
        kept = []
        for k in range(6):  # results let go of, kept, viewed and watched: filled anew or not
            M = m.mass(q[k])
            parts = m.servo_terms(q[k], qd[k])
            kept.append(m.gravity(q[k])[:1])
            watched = weakref.ref(m.jacobian(q[k]))
        M, parts = np.empty((50, 2, 2)), tuple(np.empty(a.shape) for a in m.servo_terms(q[0], qd[0]))
        m.mass(q, out=M), m.servo_terms(q[0], qd[0], out=parts)
        for bad in (M[0], M[:, ::-1], (M, M), q):
            try:
                m.mass(q, out=bad)
            except (TypeError, ValueError):
                pass
        for bad in (None, np.zeros(3), "x", np.zeros((2, 2, 2))):
            try:
                m.mass(bad)
            except (TypeError, ValueError):
                pass
        try:
            m.forward_dynamics(q[0], qd[0] * np.nan, qd[0])
        except FloatingPointError:
            pass
        print("done")
    """)
    )
    log = tmp_path / "valgrind.log"
    env = {**os.environ, "PYTHONMALLOC": "malloc"}
    result = subprocess.run(
        ["valgrind", "--leak-check=no", f"--log-file={log}", sys.executable, str(script)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert result.returncode == 0 and "done" in result.stdout, result.stderr
    # CPython itself (not built for valgrind) reports errors of its own; the module's are those
    # whose stack passes through the extension
    blocks = re.split(r"\n==\d+== \n", log.read_text())
    ours = [
        b
        for b in blocks
        if re.search(r"== (Invalid|Conditional|Use of|Syscall|Mismatched|Source and)", b) and "two_link" in b
    ]
    assert not ours, "\n\n".join(ours[:3])


def test_a_batch_of_ten_million_states(build_module):
    m = build_module(SPECS / "two_link.yaml")
    rng = np.random.default_rng(5)
    q = rng.uniform(-3, 3, (10_000_000, 2))
    g = m.gravity(q)
    assert g.shape == (10_000_000, 2)
    for k in rng.integers(0, len(q), 20):
        np.testing.assert_array_equal(g[k], m.gravity(q[k]))


def test_a_batch_too_large_to_allocate_is_a_memory_error(build_module):
    """A zero-stride view of 2^45 states: the module's conversion of its arguments (a contiguous
    copy) cannot be allocated, and the user gets a MemoryError, not a crash."""
    m = build_module(SPECS / "two_link.yaml")
    huge = np.broadcast_to(np.zeros(2), (2**45, 2))  # a view: no memory until copied
    with pytest.raises(MemoryError):
        m.gravity(huge)

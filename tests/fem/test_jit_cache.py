"""An interrupted JIT compile (Ctrl-C or SIGTERM during "compiling forms") must not break the next
run: FFCx leaves its claim MODULE.c behind on KeyboardInterrupt, and the next compile of the same
form then waits for it and times out (millimpact.fem.jit_cache)."""
from __future__ import annotations

import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

import ffcx.codegeneration.jit as ffcx_jit
from millimpact.fem.jit_cache import _release_claim, release_interrupted_compile, stale_jit_claim


def _form():
    # a form of its own (its signature names no other test's module): the coefficient 7.25
    domain = mesh.create_unit_interval(MPI.COMM_SELF, 2)
    V = fem.FunctionSpace(domain, ("Lagrange", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    return 7.25 * u * v * ufl.dx


def test_an_interrupted_compile_is_released_and_the_next_compiles(tmp_path, monkeypatch):
    params = {"cache_dir": str(tmp_path), "timeout": 2}
    a = _form()

    def interrupted(*args, **kw):   # Ctrl-C inside the C compiler's run, after FFCx claimed the module
        raise KeyboardInterrupt()

    monkeypatch.setattr(ffcx_jit, "_compile_objects", interrupted)
    with pytest.raises(KeyboardInterrupt) as exc:
        fem.form(a, jit_params=params)
    claims = list(tmp_path.glob("libffcx_forms_*.c"))
    assert len(claims) == 1 and not claims[0].with_suffix(".c.cached").exists()   # FFCx left its claim
    monkeypatch.undo()

    # without the release the next compile waits and fails with FFCx's TimeoutError, which the CLI
    # turns into one line naming the file
    with pytest.raises(TimeoutError) as timeout:
        fem.form(a, jit_params=params)
    assert stale_jit_claim(timeout.value) == str(claims[0])

    try:       # the CLI sees the interrupt a study re-raised as its own ("from None")
        try:
            raise exc.value
        except KeyboardInterrupt:
            raise KeyboardInterrupt("study interrupted") from None
    except KeyboardInterrupt as outer:
        release_interrupted_compile(outer)
    assert not claims[0].exists() and claims[0].with_suffix(".c.failed").is_file()
    assert fem.form(a, jit_params=params) is not None                               # compiles again
    assert claims[0].with_suffix(".c.cached").is_file()


def test_a_wait_for_another_process_is_not_released(tmp_path):
    """An interrupt while waiting for a module another process claimed leaves its claim alone."""
    a = _form()
    params = {"cache_dir": str(tmp_path), "timeout": 1}
    fem.form(a, jit_params=params)                                    # to learn the module's name
    (claim,) = tmp_path.glob("libffcx_forms_*.c")
    for p in tmp_path.iterdir():                                      # a fresh cache with its claim only
        if p != claim:
            p.unlink() if p.is_file() else None
    try:
        fem.form(a, jit_params=params)
    except TimeoutError as exc:        # the wait ended (an interrupt in the wait has the same frames)
        assert _release_claim(exc.__traceback__) is None
    else:
        pytest.fail("the claim was not waited for")
    assert claim.is_file()

"""An importer that unloads the library while an instance lives and loads it again.

ecos (through fmi4c) does this when two components of a system use the same FMU file: it
closes and reopens the shared library on every instantiation. Had the library really been
unloaded, its table of live instances would start again from empty and the second instance would
get the first one's handle, so that every call for the first would reach the second. The library
is linked to stay loaded once loaded (ELF's NODELETE flag, build.rs), so the first instance
survives the reload and the second gets a handle of its own.

Each check runs in a child Python process: the dynamic loader's state (a library that stays
loaded) is kept out of the test session.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest
from archives import MODELS, separate_copy

CHILD = textwrap.dedent(
    r"""
    import ctypes, sys
    so, guid, resources, tau_vr, omega_vr = sys.argv[1], sys.argv[2].encode(), sys.argv[3].encode(), int(sys.argv[4]), int(sys.argv[5])
    libc = ctypes.CDLL(None)
    libc.dlopen.restype = ctypes.c_void_p
    libc.dlopen.argtypes = [ctypes.c_char_p, ctypes.c_int]
    libc.dlsym.restype = ctypes.c_void_p
    libc.dlsym.argtypes = [ctypes.c_void_p, ctypes.c_char_p]
    libc.dlclose.argtypes = [ctypes.c_void_p]
    RTLD_NOW, RTLD_NOLOAD = 2, 4
    LOGGER = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)
    class Callbacks(ctypes.Structure):
        _fields_ = [("logger", LOGGER), ("allocate", ctypes.c_void_p), ("free", ctypes.c_void_p),
                    ("step_finished", ctypes.c_void_p), ("environment", ctypes.c_void_p)]
    messages = []
    logger = LOGGER(lambda env, name, status, category, message: messages.append((status, message)))
    callbacks = Callbacks(logger, None, None, None, None)
    P, U, R, D = ctypes.c_void_p, ctypes.c_uint, ctypes.c_double, ctypes.c_int
    SIGNATURES = {
        "fmi2Instantiate": (P, [ctypes.c_char_p, D, ctypes.c_char_p, ctypes.c_char_p, ctypes.POINTER(Callbacks), D, D]),
        "fmi2SetupExperiment": (D, [P, D, R, R, D, R]),
        "fmi2EnterInitializationMode": (D, [P]),
        "fmi2ExitInitializationMode": (D, [P]),
        "fmi2SetReal": (D, [P, ctypes.POINTER(U), ctypes.c_size_t, ctypes.POINTER(R)]),
        "fmi2GetReal": (D, [P, ctypes.POINTER(U), ctypes.c_size_t, ctypes.POINTER(R)]),
        "fmi2DoStep": (D, [P, R, R, D]),
        "fmi2FreeInstance": (None, [P]),
    }
    def functions(handle):
        out = {}
        for name, (restype, argtypes) in SIGNATURES.items():
            address = libc.dlsym(handle, name.encode())
            assert address, name
            out[name] = ctypes.CFUNCTYPE(restype, *argtypes)(address)
        return out
    def started(f, name, tau):
        c = f["fmi2Instantiate"](name, 1, guid, resources, ctypes.byref(callbacks), 0, 0)
        assert c, messages
        vr, value = (U * 1)(tau_vr), (R * 1)(tau)
        for status in (f["fmi2SetupExperiment"](c, 0, 0.0, 0.0, 0, 0.0), f["fmi2EnterInitializationMode"](c),
                       f["fmi2SetReal"](c, vr, 1, value), f["fmi2ExitInitializationMode"](c)):
            assert status == 0, messages
        return c
    def omega(f, c):
        vr, value = (U * 1)(omega_vr), (R * 1)()
        assert f["fmi2GetReal"](c, vr, 1, value) == 0, messages
        return value[0]

    def step(f, c, t):
        assert f["fmi2DoStep"](c, t, 0.01, 1) == 0, messages
        return omega(f, c)

    first = libc.dlopen(so.encode(), RTLD_NOW)
    f = functions(first)
    a = started(f, b"A", 1.0)
    a1 = step(f, a, 0.0)
    assert libc.dlclose(first) == 0
    # Still mapped after its last dlclose: NODELETE.
    print("resident", bool(libc.dlopen(so.encode(), RTLD_NOW | RTLD_NOLOAD)))
    second = libc.dlopen(so.encode(), RTLD_NOW)
    g = functions(second)
    b = started(g, b"B", -1.0)
    b1 = step(g, b, 0.0)
    a2 = step(g, a, 0.01)
    # Fresh instances run what A and B ran, with nothing in between: the same calls on the same
    # code, so the same bits.
    c = started(g, b"C", 1.0)
    c1, c2 = step(g, c, 0.0), step(g, c, 0.01)
    d = started(g, b"D", -1.0)
    d1 = step(g, d, 0.0)
    print("distinct", len({a, b, c, d}) == 4)
    print("A", (a1, a2) == (c1, c2), "B", b1 == d1 and b1 != a1)
    for x in (a, b, c, d):
        g["fmi2FreeInstance"](x)
    """
)


@pytest.mark.parametrize("model", MODELS)
def test_an_instance_survives_its_library_being_closed_and_reopened(model: str, tmp_path):
    archive = separate_copy(model)
    so = f"{archive.unzipdir}/binaries/linux64/{archive.model}.so"
    resources = f"file://{archive.unzipdir}/resources"
    script = tmp_path / "reload.py"
    script.write_text(CHILD)
    run = subprocess.run([sys.executable, str(script), so, archive.md.guid, resources, str(archive.vr["tau_m"]),
                          str(archive.vr["omega_m"])], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["resident", "True", "distinct", "True", "A", "True", "B", "True"], run.stdout

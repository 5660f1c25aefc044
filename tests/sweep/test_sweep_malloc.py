"""The sweep's fixed mmap threshold (``sweep.malloc``): set through glibc's ``mallopt`` where glibc
is the C library, left alone where ``$MALLOC_MMAP_THRESHOLD_`` is set."""

import ctypes
import ctypes.util

import pytest

from dfrmot_jax.sweep import malloc


def _glibc() -> bool:
    name = ctypes.util.find_library("c")
    try:
        return bool(name) and hasattr(ctypes.CDLL(name), "gnu_get_libc_version")
    except OSError:
        return False


@pytest.fixture
def fresh(monkeypatch):
    monkeypatch.setattr(malloc, "_done", [])
    return malloc


def test_fixed_where_glibc(fresh, monkeypatch):
    monkeypatch.delenv("MALLOC_MMAP_THRESHOLD_", raising=False)
    assert fresh.fixed_mmap_threshold() is _glibc()
    assert fresh._done == [_glibc()]
    assert fresh.fixed_mmap_threshold() is _glibc()       # once per process


def test_left_alone_with_glibc_variable(fresh, monkeypatch):
    monkeypatch.setenv("MALLOC_MMAP_THRESHOLD_", "131072")
    assert fresh.fixed_mmap_threshold() is False


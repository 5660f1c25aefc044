"""Numba's on-disk cache for a kernel that calls kernels of other modules, keyed on their source too.

Numba keys a cached function on its own source file (its size and time) and its bytecode, not on the
functions it calls: a cached kernel that calls another module's kernel would keep the old callee
after that module changed (a key short of what its value depends on). Such a kernel names the
modules it calls::

    @cached_njit(nogil=True, calls=("dfrmot_jax.metrics.common.assignment",))
    def _kernel(...):
        ... match_block(...) ...

and the digest of their source (:func:`source_digest`, taken when the kernel is defined) is part of
its cache key: any change in the callees' modules compiles it anew, while an unchanged install
loads it from disk. ``tests/metrics/kitti2d/test_metrics_units.py`` checks both. (The kernel itself is the cached
entry point: a cached wrapper around an uncached kernel, keyed by a closure over the digest, cost a
second LLVM optimisation and code generation of the whole call tree, about 1.2-1.6 s of CPU per
kernel on its first run.)

Every cached kernel is made by :func:`cached_njit` (``numba.njit(cache=True)``, with two faults of
numba's cache handled, so that the command line works wherever it runs):

* no writable cache location (``$NUMBA_CACHE_DIR``, the package's ``__pycache__`` and the home
  cache all unwritable, e.g. ``HOME=/nonexistent`` and a read-only install): numba refuses the
  decorator (``RuntimeError: cannot cache function ...: no locator available``) while the metrics are
  imported. The kernels are then kept in a folder of this user's in the temporary directory
  (:func:`temp_cache_root`), else compiled in memory, with one warning line;
* a damaged entry (an index or data file truncated, emptied or garbled): numba raises while
  loading it (``UnpicklingError``, ``EOFError``, ``UnicodeDecodeError``, ...), and every later run
  the same. The entry is compiled anew and replaced, with one warning line naming the file.

and one of numba's cost: processes that miss the same entry at once (a sweep's metric workers, two
runs at once) each compiled it, racing to write it. A process
that misses an entry now takes the kernel's lock (a file beside its index, ``filelock``: released
by the OS if the process dies) while it compiles and saves it; another one waits for the lock and
loads the saved entry (waiting at most :data:`COMPILE_WAIT_S`, then compiling it itself). Locks are
taken from caller to callee only (a kernel's callees are compiled while its lock is held), so no two
processes can each wait for the other.
"""

from __future__ import annotations

import hashlib
import multiprocessing
import os
import stat
import sys
import tempfile
import warnings
from pathlib import Path

import filelock
import numba
from numba.core.caching import CompileResultCacheImpl, FunctionCache, UserWideCacheLocator

__all__ = ["source_digest", "cached_njit", "temp_cache_root"]

#: the warnings given in this process (each once: the first kernel that meets a fault says it)
_warned: set[str] = set()
#: how long a process waits for another one compiling the same kernel before compiling it itself (s)
COMPILE_WAIT_S = 600.0


def source_digest(*modules: str) -> str:
    """The SHA-1 of the source files of the named (imported) modules, in order: the part of a cached
    kernel's key that names the kernels it calls (:func:`cached_njit`'s ``calls``)."""
    h = hashlib.sha1()
    for name in modules:
        h.update(name.encode() + b"\0" + Path(sys.modules[name].__file__).read_bytes())
    return h.hexdigest()


def temp_cache_root() -> str:
    """The folder of this user's compiled kernels in the temporary directory, where no other cache
    location is writable (used only when owned by this user and writable by no one else)."""
    uid = os.getuid() if hasattr(os, "getuid") else "user"
    return os.path.join(tempfile.gettempdir(), f"dfrmot_jax-numba-{uid}")


def _warn_once(key: str, message: str) -> None:
    """One warning line per ``key`` and process; none in the worker processes of a pool (their
    parent has said it)."""
    if key in _warned or multiprocessing.parent_process() is not None:
        return
    _warned.add(key)
    warnings.warn(message, RuntimeWarning, stacklevel=4)


class _TempCacheLocator(UserWideCacheLocator):
    """numba's user-wide cache location moved to :func:`temp_cache_root`: the last one tried."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        self._cache_path = os.path.join(temp_cache_root(), self.get_suitable_cache_subpath(py_file))

    def ensure_cache_path(self):
        root = temp_cache_root()
        os.makedirs(root, mode=0o700, exist_ok=True)
        st = os.lstat(root)
        if not stat.S_ISDIR(st.st_mode) or (hasattr(os, "getuid") and st.st_uid != os.getuid()) or \
                st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
            raise PermissionError(f"{root}: not a folder of this user's alone")
        super().ensure_cache_path()


class _KernelCacheImpl(CompileResultCacheImpl):
    _locator_classes = [*CompileResultCacheImpl._locator_classes, _TempCacheLocator]


class _KernelCache(FunctionCache):
    """numba's cache of one function, with the temporary folder as its last location and a damaged
    entry compiled anew and replaced (module docstring)."""

    _impl_class = _KernelCacheImpl

    def __init__(self, py_func, calls_digest: str = ""):
        self._calls_digest = calls_digest
        self._held: filelock.BaseFileLock | None = None     # this kernel's lock, while compiling it
        super().__init__(py_func)
        if isinstance(self._impl.locator, _TempCacheLocator):
            _warn_once("temp", f"no writable cache for the compiled scoring kernels ($NUMBA_CACHE_DIR, the "
                               f"package's __pycache__, the home cache): kept in {temp_cache_root()}")

    def _index_key(self, sig, codegen):
        """numba's key of an entry, with the digest of the modules the kernel calls (module docstring)."""
        key = super()._index_key(sig, codegen)
        return (*key, self._calls_digest) if self._calls_digest else key

    def load_overload(self, sig, target_context):
        """The cached entry of ``sig``, or None: then numba compiles it and :meth:`save_overload` saves
        it. Where another process is compiling this kernel (it holds the kernel's lock), its entry is
        waited for and loaded: one compilation per kernel, not one per process (module docstring)."""
        self._release()                 # (a compilation of this kernel that raised since)
        cres = self._load(sig, target_context)
        if cres is not None or not self._enabled:
            return cres
        lock = self._lock()
        if lock is None:
            return None
        try:
            lock.acquire(timeout=COMPILE_WAIT_S)
        except (filelock.Timeout, OSError):       # waited long enough, or no lock here: compiled here
            return None
        cres = self._load(sig, target_context)    # compiled meanwhile by the process that held the lock
        if cres is not None:
            lock.release()
            return cres
        self._held = lock               # held while this process compiles it, until saved
        return None

    def _lock(self) -> filelock.BaseFileLock | None:
        """The lock of this kernel's entries (beside its index), or None where there is no folder for it."""
        try:
            self._impl.locator.ensure_cache_path()
            return filelock.FileLock(self._cache_file._index_path + ".lock", thread_local=False)
        except Exception:
            return None

    def _release(self) -> None:
        lock, self._held = self._held, None
        if lock is not None:
            lock.release()

    def _load(self, sig, target_context):
        try:
            return super().load_overload(sig, target_context)
        except Exception as e:          # any damage: pickle, EOF, decoding, numba's own rebuilding
            path = self._damaged_file(sig, target_context)
            try:
                os.unlink(path)
                done = "compiled anew and replaced"
            except OSError as err:
                done = f"compiled anew (it cannot be replaced: {err.strerror or err})"
            _warn_once(path, f"damaged compiled-kernel cache entry {path} ({type(e).__name__}): {done}")
            return None

    def save_overload(self, sig, data):
        try:
            super().save_overload(sig, data)
        except Exception as e:          # a damaged index that could not be removed, a full disk: kept in memory
            path = self._cache_file._index_path
            _warn_once(f"save {path}", f"compiled kernel not kept in {path} ({type(e).__name__}: {e})")
        finally:
            self._release()

    def _damaged_file(self, sig, target_context) -> str:
        """The file of the entry of ``sig`` that does not load: the index, or its data file."""
        cache_file = self._cache_file
        try:
            name = cache_file._load_index().get(self._index_key(sig, target_context.codegen()))
        except Exception:
            return cache_file._index_path
        return cache_file._index_path if name is None else cache_file._data_path(name)


def cached_njit(*, calls: tuple[str, ...] = (), **options):
    """``numba.njit(cache=True, **options)`` with numba's cache faults handled (module docstring):
    the decorator of every cached kernel of the metrics. ``calls``: the (imported) modules whose
    kernels it calls, their source part of its cache key."""
    def wrap(func):
        kernel = numba.njit(**options)(func)
        try:                            # (what numba's Dispatcher.enable_caching sets)
            kernel._cache = _KernelCache(kernel.py_func, source_digest(*calls) if calls else "")
        except RuntimeError:            # no location at all: compiled in memory
            _warn_once("memory", f"no writable cache for the compiled scoring kernels ($NUMBA_CACHE_DIR, the "
                                 f"package's __pycache__, the home cache, {temp_cache_root()}): compiled in memory, "
                                 f"for this run only (set NUMBA_CACHE_DIR to a writable folder to keep them)")
        return kernel
    return wrap

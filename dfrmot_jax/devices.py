"""Where the tracker runs: one XLA CPU device per core, so that a batch of settings is split over
the cores, or a GPU.

The platform: ``$DFRMOT_DEVICE`` = ``auto`` (default: JAX's default backend, a GPU where JAX sees
one, i.e. after ``pip install -e ".[cuda]"`` on a machine with an NVIDIA GPU), ``cpu`` or ``gpu``
(:func:`chosen_platform`). A batch is split over that platform's devices (:func:`batch_devices`) and
runs ``lanes_per_call`` lanes per compiled call, by default :data:`LANES_PER_CALL` of the platform
(a GPU wants wide batches; a CPU core a few dozen lanes).

Compiled programs can be kept on disk between processes: ``$DFRMOT_COMPILE_CACHE`` names a folder
for JAX's persistent compilation cache (:func:`setup_compile_cache`; ``dfrmot`` uses
``~/.cache/dfrmot_jax/xla`` unless the variable says otherwise, ``off`` for none; a library caller
sets the variable or calls it). A program found there skips XLA's compilation (about 2.5 s of a
tracker program's 3.5 s on the CPU); the key is JAX's own (the program, the compiler options, the
device kind and the JAX version), so a cached program is the one that would be compiled.

Nothing happens at import: ``setup_host_devices`` runs at the first tracking call (or call it
yourself right after ``import dfrmot_jax``). It can only take effect before JAX initialises its
backend, i.e. before the process runs its first JAX operation; later it warns once when JAX runs
on fewer devices than asked for.
"""

from __future__ import annotations

import os
import tempfile
import time
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, TypeVar

import jax

ENV_VAR = "DFRMOT_HOST_DEVICES"
#: a folder for compiled programs kept between processes (``off``, ``0`` or empty: none)
COMPILE_CACHE_VAR = "DFRMOT_COMPILE_CACHE"
MIN_COMPILE_VAR = "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"   # JAX reads it itself
#: the most the compile cache folder holds (JAX evicts the least recently used entries beyond it)
COMPILE_CACHE_MAX_BYTES = 1 << 30
DEVICE_VAR = "DFRMOT_DEVICE"
DEVICE_CHOICES = ("auto", "cpu", "gpu")
#: default lanes per compiled tracker call, by platform
LANES_PER_CALL = {"cpu": 64, "gpu": 1024}
_FORCE_FLAG = "xla_force_host_platform_device_count"
_warned = False
#: compile cache folders refused in this process (not writable), each said once
_refused_caches: set[str] = set()
T = TypeVar("T")


def wanted_devices() -> int:
    """``$DFRMOT_HOST_DEVICES`` (a whole number; 0 or empty: the default), else one per core (at
    most 8); anything else is a ValueError naming the variable."""
    text = os.environ.get(ENV_VAR, "").strip()
    try:
        n = int(text or 0)
    except ValueError:
        n = -1
    if n < 0:
        raise ValueError(f"{ENV_VAR}={text!r}: expected a whole number of CPU devices >= 1 (0 or unset: one per "
                         f"core, at most 8)")
    return n or min(os.cpu_count() or 1, 8)


def setup_host_devices(n: int | None = None) -> int:
    """Ask JAX for ``n`` CPU devices (default :func:`wanted_devices`); returns the devices in use.

    A ``--xla_force_host_platform_device_count`` in ``XLA_FLAGS`` wins. Once JAX's backend is
    running the count cannot change: then a RuntimeWarning says so (once) if it is smaller.
    """
    global _warned
    setup_compile_cache()
    want = wanted_devices() if n is None else int(n)
    if _FORCE_FLAG not in os.environ.get("XLA_FLAGS", ""):
        try:
            jax.config.update("jax_num_cpu_devices", want)
        except RuntimeError:      # the backend is already initialised: nothing can change now
            pass
    have = jax.local_device_count()
    if have < want and jax.default_backend() == "cpu" and not _warned:
        _warned = True
        warnings.warn(f"JAX was initialised with {have} CPU device(s) before dfrmot_jax could ask for {want}: "
                      f"batches run on {have} core(s). Call dfrmot_jax.setup_host_devices() right after import, "
                      f"before any JAX operation, or set XLA_FLAGS=--{_FORCE_FLAG}={want}.",
                      RuntimeWarning, stacklevel=3)
    return have


def setup_compile_cache(folder: str | os.PathLike | None = None) -> str | None:
    """Keep compiled programs in ``folder`` (default ``$DFRMOT_COMPILE_CACHE``; ``off``, ``0`` or
    empty: none) through JAX's persistent compilation cache, for the programs whose compilation
    takes 0.5 s or more (JAX's ``$JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS``, where set, instead),
    at most :data:`COMPILE_CACHE_MAX_BYTES`. A cache folder the process has
    already set (JAX's ``jax_compilation_cache_dir``) is left as it is. Returns the folder in use, or None."""
    current = jax.config.jax_compilation_cache_dir
    if current:
        return current
    folder = os.environ.get(COMPILE_CACHE_VAR, "") if folder is None else os.fspath(folder)
    if folder.strip().lower() in ("", "0", "off", "none", "false"):
        return None
    folder = os.path.expanduser(folder)
    if folder in _refused_caches:
        return None
    problem = _unwritable(folder)
    if problem is not None:     # JAX would warn at every read and write of it (its reads take a lock file too)
        _refused_caches.add(folder)
        warnings.warn(f"{COMPILE_CACHE_VAR}: {folder}: {problem}: compiled programs are not kept between runs "
                      f"(name a writable folder, or {COMPILE_CACHE_VAR}=off)", RuntimeWarning, stacklevel=2)
        return None
    jax.config.update("jax_compilation_cache_dir", folder)
    if MIN_COMPILE_VAR not in os.environ:     # JAX's own variable, where set, decides
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    jax.config.update("jax_compilation_cache_max_size", COMPILE_CACHE_MAX_BYTES)
    return folder


def _unwritable(folder: str) -> str | None:
    """Why ``folder`` cannot hold the compile cache (made if missing), None when it can."""
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError as e:
        return f"not writable ({e.strerror or e})"
    return None


def _entries_read_since(folder: str, t0: int) -> list[Path]:
    """The compile cache entries of ``folder`` read since ``t0`` (``time.time_ns()``): JAX's cache
    stamps an entry's ``-atime`` file at each read."""
    read = []
    for stamp in Path(folder).glob("*-atime"):
        try:
            if int.from_bytes(stamp.read_bytes()[:8], "little") >= t0:
                read.append(stamp.with_name(stamp.name.removesuffix("-atime") + "-cache"))
        except OSError:
            continue
    return read


#: the start of JAX's warning about a compile cache entry it cannot read (it then compiles the program,
#: but leaves the entry: every later run would warn and compile again)
_READ_ERROR = "Error reading persistent compilation cache entry"


def _drop_read_entries(folder: str, t0: int) -> list[Path]:
    """Remove the entries of compile cache ``folder`` read since ``t0``; returns them."""
    read = _entries_read_since(folder, t0)
    for entry in read:
        for path in (entry, entry.with_name(entry.name.removesuffix("-cache") + "-atime")):
            path.unlink(missing_ok=True)
    return read


@contextmanager
def _replacing_unreadable_entries(t0: int):
    """Inside, JAX's warning that a compile cache entry cannot be read (truncated, garbled) removes the
    entries read since ``t0`` as it is shown, so that the program JAX then compiles is kept in their
    place; the warning says so."""
    folder = jax.config.jax_compilation_cache_dir
    if not folder:
        yield
        return
    with warnings.catch_warnings():
        shown = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            if str(message).startswith(_READ_ERROR):
                gone = _drop_read_entries(folder, t0)
                message = f"{message} ({', '.join(str(p) for p in gone) or 'in ' + folder}: compiled anew and replaced)"
            shown(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        yield


def call_compiled(call: Callable[[], T]) -> T:
    """``call()``, a call of a jitted program; where it fails (JAX's checks of a loaded executable, an
    ``AssertionError`` or a runtime error) after reading entries of the compile cache, those entries
    did not load as their programs (swapped or tampered with): they are removed, with one warning
    naming them, and the call is made again, compiling anew (and keeping the new programs). An entry
    JAX cannot read at all (its own warning) is replaced by the program compiled in its place."""
    t0 = time.time_ns()
    try:
        with _replacing_unreadable_entries(t0):
            return call()
    except (AssertionError, jax.errors.JaxRuntimeError) as e:
        folder = jax.config.jax_compilation_cache_dir
        read = _drop_read_entries(folder, t0) if folder else []
        if not read:
            raise
        warnings.warn(f"compile cache entries that do not load as their programs ({type(e).__name__}: {e}): "
                      f"{', '.join(str(p) for p in read)}: compiled anew and replaced", RuntimeWarning, stacklevel=2)
        jax.clear_caches()
    return call()


def platform_of(backend: str) -> str:
    """JAX's backend name as a platform of :data:`DEVICE_CHOICES`: ``cuda`` / ``rocm`` / ``gpu`` -> ``gpu``."""
    return "gpu" if backend in ("gpu", "cuda", "rocm") else backend


def chosen_platform(device: str | None = None) -> str:
    """The platform the tracker runs on: ``device`` or else ``$DFRMOT_DEVICE`` (``auto``, ``cpu``,
    ``gpu``; default ``auto``: JAX's default backend). Asking for ``gpu`` where JAX sees none (or for
    anything else) raises a ValueError (bad input: ``dfrmot`` exits 2) that says how to install the
    GPU build."""
    want = (device or os.environ.get(DEVICE_VAR, "") or "auto").strip().lower()
    if want == "cuda":
        want = "gpu"
    if want not in DEVICE_CHOICES:
        raise ValueError(f"{DEVICE_VAR}={want!r}: expected one of {', '.join(DEVICE_CHOICES)}")
    setup_host_devices()          # (asking JAX for its backend starts it: the CPU device count first)
    if want == "auto":
        return platform_of(jax.default_backend())
    if want == "gpu":
        try:
            found = jax.devices("gpu")
        except RuntimeError:
            found = []
        if not found:
            raise ValueError(f"{DEVICE_VAR}=gpu, but JAX sees no GPU (backend {jax.default_backend()!r}): install "
                             f"the GPU build with pip install -e \".[cuda]\" on a machine with an NVIDIA GPU and "
                             f"its driver, or leave {DEVICE_VAR} unset to run on the CPU")
    return want


def batch_devices(platform: str | None = None) -> list:
    """The devices a batch is split over: the CPU devices (:func:`setup_host_devices`) or the GPUs."""
    platform = chosen_platform() if platform is None else platform
    setup_host_devices()
    return jax.devices(platform)


def default_lanes_per_call(platform: str | None = None) -> int:
    """Lanes per compiled tracker call on ``platform`` (default: the chosen one): :data:`LANES_PER_CALL`."""
    return LANES_PER_CALL[chosen_platform() if platform is None else platform]

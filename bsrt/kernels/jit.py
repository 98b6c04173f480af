"""numba's ``njit``, with bsrt's kernels cached in the user's cache folder and loaded fast.

Every kernel module takes ``njit`` from here, so the first kernel module
imported installs :class:`KernelCacheLocator` in front of numba's own
locators (it answers only for functions of ``bsrt.kernels``; any other
numba function in the process is cached as numba would), and every kernel's
machine code loads through :class:`KernelCache` (without numba's registry
refresh, its kept bitcode parsed only when needed: a small render's loads
take about 25 instead of 200 ms). The machine code goes to

    $NUMBA_CACHE_DIR (numba's own setting, when set), else
    $XDG_CACHE_HOME/bsrt/kernels (default ~/.cache/bsrt/kernels),

in a subfolder per source folder (as numba names them: two checkouts never
share an index), never inside site-packages, which may be read-only. Where
that folder cannot be written, the package's ``__pycache__`` is used, and
last a folder in the temporary directory; where none can be written numba
raises at import (it cannot cache), which no real system does. No compiler and no network are needed: numba compiles
with its own LLVM.

When bsrt's version or :data:`CACHE_EPOCH` changes, the machine code in the
folder used is dropped once (numba's index pickles the argument types of
each kernel by module path and loads them before it compares the source's
hash: an index written before such a type moved would fail to load with
ModuleNotFoundError instead of being recompiled).

numba checks a kernel's cached machine code against a hash of the kernel's
own source file, but a kernel inlines the kernels it calls from other files
of the package: :meth:`KernelCacheLocator.get_source_stamp` hashes every
source file of the kernel's folder instead (as they were when the kernel's
module was imported), so an edit to any kernel recompiles all of them (in a
development checkout; an installed bsrt changes only with its version).
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import tempfile


def _numpy_functions_without_the_blas_probe() -> None:
    """Import numba's NumPy functions (which the first kernel call would import anyway) while
    ``scipy.linalg.cython_blas`` reads as absent: numba imports it there only to choose how
    ``np.convolve``/``np.correlate`` take inner products (which no bsrt kernel uses), and
    importing scipy.linalg costs 0.2-0.3 s of every start-up. ``np.dot`` and ``np.linalg``
    still import it when a kernel (anyone's) first uses them. Nothing is done where numba's
    NumPy functions are already imported."""
    if "numba.np.arraymath" in sys.modules or "scipy.linalg.cython_blas" in sys.modules:
        return
    sys.modules["scipy.linalg.cython_blas"] = None  # an import of it raises ImportError
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        if sys.modules.get("scipy.linalg.cython_blas", 0) is None:
            del sys.modules["scipy.linalg.cython_blas"]


_numpy_functions_without_the_blas_probe()

import llvmlite.binding as llvm  # noqa: E402
import numba  # noqa: E402
from numba.core import caching, config  # noqa: E402
from numba.core.codegen import JITCodeLibrary  # noqa: E402
from numba.core.compiler_lock import global_compiler_lock  # noqa: E402
from numba.core.registry import CPUDispatcher  # noqa: E402
from numba.core.runtime import rtsys  # noqa: E402

__all__ = ["CACHE_EPOCH", "KernelCacheLocator", "cache_root", "njit", "njit_typed"]

#: bump when a type the kernels take as an argument (a NamedTuple) moves to another module
CACHE_EPOCH = 4
_PACKAGE = __name__.rsplit(".", 1)[0]  # "bsrt.kernels"
_checked: set[str] = set()  # folders whose epoch marker was checked in this process
_writable: set[str] = set()  # folders found writable in this process


def cache_root() -> str:
    """The folder under which the kernels' machine code is cached (created on demand):
    $NUMBA_CACHE_DIR, else $XDG_CACHE_HOME/bsrt/kernels, else ~/.cache/bsrt/kernels."""
    if config.CACHE_DIR:
        return config.CACHE_DIR
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "bsrt", "kernels")


def drop_stale_machine_code(folder: str) -> None:
    """Empty ``folder`` of numba cache files once if they were written by another bsrt version
    or CACHE_EPOCH (a marker file records which); nothing happens where it cannot be written."""
    if folder in _checked:
        return
    _checked.add(folder)
    from bsrt import __version__

    marker = os.path.join(folder, "bsrt-kernels-epoch")
    stamp = f"{__version__} {CACHE_EPOCH}\n"
    try:
        with open(marker) as f:
            if f.read() == stamp:
                return
    except OSError:
        pass
    try:
        os.makedirs(folder, exist_ok=True)
        for name in os.listdir(folder):
            if name.endswith((".nbi", ".nbc")):
                os.unlink(os.path.join(folder, name))
        with open(marker, "w") as f:
            f.write(stamp)
    except OSError:
        pass


class LoadedLibrary(JITCodeLibrary):
    """A kernel's machine code loaded from the cache, whose LLVM bitcode (kept in the cache for
    linking the kernel into kernels compiled later) is parsed only when that happens or when a
    symbol the machine code does not define is asked for. numba parses it at every load: 50 of
    the 90 ms that a small render's 15 loads take, and 15 ms more to list its symbols."""

    _bitcode = b""

    @classmethod
    def _unserialize(cls, codegen, state):
        name, kind, data = state
        if kind != "object":
            return super()._unserialize(codegen, state)
        library = codegen.create_library(name)  # this class: KernelCache.load_overload
        library._bitcode = data[1]
        library.enable_object_caching()
        library._set_compiled_object(data[0])
        library._finalize_final_module()  # the machine code is loaded here
        return library

    def _parse_bitcode(self) -> None:
        if self._shared_module is None and self._bitcode:
            self._shared_module = llvm.parse_bitcode(self._bitcode)
            self._codegen._engine._load_defined_symbols(self._shared_module)

    def _get_module_for_linking(self):
        self._parse_bitcode()
        return super()._get_module_for_linking()

    def get_pointer_to_function(self, name):
        engine = self._codegen._engine
        if not engine.is_symbol_defined(name):
            if engine.get_function_address(name):  # defined by the loaded machine code
                engine._defined_symbols.add(name)
            else:
                self._parse_bitcode()
        return super().get_pointer_to_function(name)


def prepare_runtime() -> None:
    """Set up numba's runtime (NRT), which every kernel load needs first: 25-50 ms, mostly LLVM
    compiling outside the GIL, so a thread can do it while the render is being set up."""
    from numba.core.registry import cpu_target

    rtsys.initialize(cpu_target.target_context)


class KernelCache(caching.FunctionCache):
    """numba's cache of a kernel's machine code, loaded faster than numba loads it: without
    refreshing numba's typing and lowering registries first (a loaded kernel is only called,
    never typed or lowered, and numba's compiler refreshes them itself before any compile: the
    imports of numba's implementations and the typing context's refresh are about 85 ms of a
    process's first load; only the runtime (NRT), whose symbols the machine code links against,
    is set up), and with its bitcode parsed only when needed (:class:`LoadedLibrary`)."""

    def load_overload(self, sig, target_context):
        rtsys.initialize(target_context)
        codegen = target_context.codegen()
        lazy = type(codegen)._library_class is JITCodeLibrary and "_library_class" not in vars(codegen)
        with global_compiler_lock:  # numba creates libraries only under it: the swap is seen by this load alone
            if lazy:
                codegen._library_class = LoadedLibrary
            try:
                with self._guard_against_spurious_io_errors():
                    return self._load_overload(sig, target_context)
            finally:
                if lazy:
                    del codegen._library_class


class _DeferredCache:
    """A kernel's :class:`KernelCache` until numba first asks for it (to load, to save, for its
    folder), then made and put on the dispatcher: making one reads the cache folder and the
    source stamp (about 0.2 ms), and a render uses a few of the 80 kernels imported."""

    __slots__ = ("_dispatcher",)

    def __init__(self, dispatcher):
        self._dispatcher = dispatcher

    def __getattr__(self, name):
        cache = self._dispatcher._cache = KernelCache(self._dispatcher.py_func)
        return getattr(cache, name)


def _cached(dispatcher):
    """The dispatcher, its machine code cached through :class:`KernelCache` (made at first use,
    under the sources of its module's import: source_stamp_at_import)."""
    if _ours(dispatcher.py_func):  # others are left to numba's own locators
        source_stamp_at_import(dispatcher.py_func)
    dispatcher._cache = _DeferredCache(dispatcher)
    return dispatcher


# numba gives every compiled function a C-callable wrapper (for ctypes and cfunc addresses), which
# bsrt never calls. Without them compiling every kernel in one process took 31.4 instead of 32.3 s
# (medians of 3, alternating).
NO_CFUNC_WRAPPER = {"no_cfunc_wrapper": True}


def njit(*args, **options):
    """numba's ``njit`` (the same arguments), without the C wrapper (NO_CFUNC_WRAPPER); with
    ``cache=True`` the kernel's machine code is cached through :class:`KernelCache`. No kernel
    passes signatures here (``njit_typed`` does)."""
    options = {**NO_CFUNC_WRAPPER, **options}
    if not options.get("cache"):
        return numba.njit(*args, **options)
    if args:  # @njit(cache=True) only: a signature would compile before the cache is in place
        raise TypeError("bsrt's njit takes options only; use njit_typed for a signature")
    options.pop("cache")
    decorate = numba.njit(**options)
    return lambda func: _cached(decorate(func))


class OneSignatureDispatcher(CPUDispatcher):
    """A kernel of one explicit signature, compiled (or loaded from the cache) when a kernel that
    calls it is first compiled, or when it is first called, not when its module is imported: a
    process that loads its callers' machine code from the cache never compiles nor loads it."""

    signature = ""  # numba's signature string (set by njit_typed)

    def _compile_signature(self) -> None:
        if self._can_compile:
            self.compile(self.signature)
            self.disable_compile()  # other argument types convert to it, as with njit("...")

    def get_call_template(self, args, kws):  # a caller being compiled
        self._compile_signature()
        return super().get_call_template(args, kws)

    def _compile_for_args(self, *args, **kws):  # a call from Python
        self._compile_signature()
        return self(*args, **kws)


def njit_typed(signature: str, *, cache: bool = False, **options):
    """``njit(signature, ...)`` compiled at the first use instead of at import
    (:class:`OneSignatureDispatcher`): one specialisation whatever its callers pass (literal or
    variable integers), without the compile (0.5-5 s) or the cache load (~40 ms) at import."""

    def wrap(func):
        dispatcher = OneSignatureDispatcher(
            func, locals={}, targetoptions={**NO_CFUNC_WRAPPER, **options, "nopython": True}
        )
        dispatcher.signature = signature
        return _cached(dispatcher) if cache else dispatcher

    return wrap


def folder_source_stamp(folder: str) -> bytes:
    """SHA-256 over the names and contents of the folder's ``*.py`` files, in name order
    (each file's (mtime, size) keys the memo, so an edit while the process runs is seen)."""
    names = sorted(n for n in os.listdir(folder) if n.endswith(".py"))
    stats = tuple((n, os.stat(os.path.join(folder, n))) for n in names)
    return _hash_files(folder, tuple((n, st.st_mtime_ns, st.st_size) for n, st in stats))


@functools.cache
def _hash_files(folder: str, files: tuple) -> bytes:
    digest = hashlib.sha256()
    for name, _, _ in files:
        digest.update(name.encode() + b"\0")
        with open(os.path.join(folder, name), "rb") as f:
            digest.update(f.read())
    return digest.digest()


_import_stamps: dict[str, bytes] = {}  # module name -> its folder's source stamp when its kernels were made


def source_stamp_at_import(py_func) -> bytes:
    """The stamp (:func:`folder_source_stamp`) of the folder of ``py_func``'s module, as it was
    when the module's first kernel was made: the kernel's machine code is cached under the
    sources it was compiled from, even when its cache is made later (:class:`_DeferredCache`)
    and a file was edited in between. Computed once per module."""
    module = py_func.__module__
    if module not in _import_stamps:
        folder = os.path.dirname(os.path.abspath(py_func.__code__.co_filename))
        _import_stamps[module] = folder_source_stamp(folder)
    return _import_stamps[module]


class KernelCacheLocator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
    """numba's cache locator for bsrt's kernels: :func:`cache_root` / <source folder's name and hash>;
    the machine code is valid while no source file of the folder changes (:func:`source_stamp_at_import`)."""

    def __init__(self, py_func, py_file):
        self._py_func = py_func
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = os.path.join(cache_root(), self.get_suitable_cache_subpath(py_file))

    def get_cache_path(self):
        return self._cache_path

    def get_source_stamp(self):
        return source_stamp_at_import(self._py_func)

    def ensure_cache_path(self):
        if self._cache_path in _writable:  # checked once per folder (numba writes a file to check, per kernel)
            return
        super().ensure_cache_path()
        drop_stale_machine_code(self._cache_path)
        _writable.add(self._cache_path)

    @classmethod
    def from_function(cls, py_func, py_file):
        if not _ours(py_func):
            return None
        return super().from_function(py_func, py_file)


class PackageCacheLocator(KernelCacheLocator):
    """Where the user's cache folder cannot be written: the package's own ``__pycache__``."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        self._cache_path = os.path.join(os.path.dirname(py_file), "__pycache__")


class TemporaryCacheLocator(KernelCacheLocator):
    """The last resort: a folder in the temporary directory (per user)."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        user = os.getuid() if hasattr(os, "getuid") else 0
        folder = os.path.join(tempfile.gettempdir(), f"bsrt-kernels-{user}")
        self._cache_path = os.path.join(folder, self.get_suitable_cache_subpath(py_file))


LOCATORS = (KernelCacheLocator, PackageCacheLocator, TemporaryCacheLocator)  # tried in this order


def _ours(py_func) -> bool:
    module = getattr(py_func, "__module__", "") or ""
    return module == _PACKAGE or module.startswith(_PACKAGE + ".")


def _install() -> None:
    """Put bsrt's locators in front of numba's own (once)."""
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # renamed in numba 0.61
    classes = impl._locator_classes
    if KernelCacheLocator not in classes:
        classes[:0] = LOCATORS


_install()

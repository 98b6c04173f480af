"""The one place that creates OpenGL contexts and loads shaders.

Headless rendering uses EGL (``backend="egl"``; without it glcontext would try
X11). EGL device 0 can be an unusable DRM node, so devices are tried in turn;
``GLCONTEXT_DEVICE_INDEX`` (or ``BSRT_EGL_DEVICE``) picks one explicitly.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import os
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import moderngl

from bsrt.errors import RenderError

GL_VERSION = 330  # what the map needs
GL_COMPUTE_VERSION = 450  # compute shaders and GL_ARB_gpu_shader_fp64 (the GPU solve, rendering/gpu.py)
FIX_HINT = (
    "install Mesa's EGL and OpenGL drivers (Debian/Ubuntu: apt-get install libegl1 libgl1 "
    "libegl-mesa0 libgl1-mesa-dri), or pick a device with GLCONTEXT_DEVICE_INDEX=N; "
    "`bsrt doctor` lists the devices"
)


class _Egl:
    """libEGL through ctypes with EGL_EXT_device_enumeration: ``devices`` (handles), ``describe``
    and ``initialise`` of a device's display. None where EGL or the extension is missing."""

    def __init__(self, egl: ctypes.CDLL, query_ptr: int, string_ptr: int, display_ptr: int):
        self.egl = egl
        self._query = ctypes.CFUNCTYPE(
            ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_int)
        )(query_ptr)
        self._string = ctypes.CFUNCTYPE(ctypes.c_char_p, ctypes.c_void_p, ctypes.c_int)(string_ptr)
        self._display = (
            ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_uint, ctypes.c_void_p, ctypes.c_void_p)(display_ptr)
            if display_ptr
            else None
        )

    @classmethod
    def load(cls) -> _Egl | None:
        name = _library("EGL")
        if not name:
            return None
        try:
            egl = ctypes.CDLL(name)
        except OSError:
            return None
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        query_ptr = egl.eglGetProcAddress(b"eglQueryDevicesEXT")
        string_ptr = egl.eglGetProcAddress(b"eglQueryDeviceStringEXT")
        if not query_ptr or not string_ptr:
            return None
        return cls(egl, query_ptr, string_ptr, egl.eglGetProcAddress(b"eglGetPlatformDisplayEXT"))

    def devices(self) -> list:
        count = ctypes.c_int(0)
        if not self._query(0, None, ctypes.byref(count)) or count.value <= 0:
            return []
        devices = (ctypes.c_void_p * count.value)()
        self._query(count.value, devices, ctypes.byref(count))
        return list(devices[: count.value])

    def describe(self, device) -> str:
        return _describe_device(lambda name: self._string(device, name))

    def initialise(self, device) -> None:
        """eglInitialize the device's display (EGL_PLATFORM_DEVICE_EXT): the driver loads here."""
        if self._display is None:
            return
        display = self._display(0x313F, device, None)  # EGL_PLATFORM_DEVICE_EXT
        if display:
            self.egl.eglInitialize.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
            self.egl.eglInitialize(display, None, None)


def egl_devices() -> list[str]:
    """Describe each EGL device (DRM node or 'software'), [] if EGL is missing.

    Uses EGL_EXT_device_enumeration through ctypes; best effort, for
    ``bsrt doctor`` only.
    """
    egl = _Egl.load()
    return [egl.describe(device) for device in egl.devices()] if egl else []


def chosen_device() -> int | None:
    """The EGL device named by BSRT_EGL_DEVICE / GLCONTEXT_DEVICE_INDEX, None where neither is set."""
    chosen = os.environ.get("BSRT_EGL_DEVICE", os.environ.get("GLCONTEXT_DEVICE_INDEX"))
    return None if chosen is None else int(chosen)


@functools.cache
def _library(name: str) -> str | None:
    """ctypes' file name of the system library ``name`` ("EGL", "GL"), or None; found once per
    process (each search runs ``ldconfig -p``, 1-2 ms, which glcontext would run per context)."""
    return ctypes.util.find_library(name)


def load_driver() -> None:
    """Initialise the EGL display of the device that create_headless_context tries first, where
    the driver loads (20-40 ms with Mesa): called from a thread ahead of the context (the GIL is
    released in EGL), the context then takes 5-15 ms. Best effort: any failure is left to
    create_headless_context to report."""
    try:
        _library("GL")
        egl = _Egl.load()
        devices = egl.devices() if egl else []
        index = chosen_device() or 0
        if index < len(devices):
            egl.initialise(devices[index])
    except Exception:  # noqa: BLE001 - only a head start; the context's own creation reports
        pass


def _describe_device(query) -> str:
    """One EGL device in words from query(name) -> bytes or None (eglQueryDeviceStringEXT):
    its vendor and renderer where EGL_EXT_device_query_name gives them, NVIDIA's
    devices named by EGL_NV_device_cuda, and the DRM node where there is one."""
    egl_extensions, egl_vendor, egl_renderer, egl_drm_device_file = 0x3055, 0x3053, 0x335F, 0x3233

    def text(name: int) -> str:
        value = query(name)
        return value.decode(errors="replace").strip() if value else ""

    ext = text(egl_extensions)
    drm = text(egl_drm_device_file) if "EGL_EXT_device_drm" in ext else ""
    name = ""
    if "EGL_EXT_device_query_name" in ext:
        vendor, renderer = text(egl_vendor), text(egl_renderer)
        if vendor and renderer.startswith(vendor):  # NVIDIA's: vendor "NVIDIA", renderer "NVIDIA H200"
            vendor = ""
        name = " ".join(x for x in (vendor, renderer) if x)
    if not name and "EGL_NV_device_cuda" in ext:
        name = "NVIDIA (CUDA device)"
    if not name and "EGL_MESA_device_software" in ext:
        name = "software (Mesa llvmpipe)"
    if name and drm:
        return f"{name} ({drm})"
    return name or drm or "unknown device"


def create_headless_context() -> moderngl.Context:
    """A standalone OpenGL context through EGL: 4.5 core where the device
    offers it (compute shaders, the GPU solve), else 3.3 core (the map alone).

    Tries the device named by GLCONTEXT_DEVICE_INDEX / BSRT_EGL_DEVICE, else
    each device in turn. Raises RenderError with a fix when none works.
    """
    chosen = chosen_device()
    if chosen is not None:
        candidates = [chosen]
    else:
        egl = _Egl.load()
        candidates = list(range(max(1, len(egl.devices()) if egl else 0)))
    errors = []
    for index in candidates:
        for version in (GL_COMPUTE_VERSION, GL_VERSION):
            try:
                return moderngl.create_context(
                    standalone=True,
                    backend="egl",
                    require=version,
                    device_index=index,
                    libgl=_library("GL"),
                    libegl=_library("EGL"),
                )
            except Exception as exc:  # glcontext raises plain Exception subclasses
                if version == GL_VERSION:
                    errors.append(f"device {index}: {exc}")
    raise RenderError("no OpenGL context through EGL (" + "; ".join(errors) + "); " + FIX_HINT)


def _shader_file(filename: str) -> str:
    """The text of shaders/FILENAME.

    An installed wheel ships the top-level shaders/ as the package
    bsrt.shaders; running from a source checkout (bsrt/ imported from the
    working tree) reads the checkout's shaders/ directly.
    """
    try:
        folder = resources.files("bsrt.shaders")
    except ModuleNotFoundError:
        folder = Path(__file__).resolve().parents[2] / "shaders"  # bsrt/rendering/gl.py -> the checkout
    return folder.joinpath(filename).read_text(encoding="utf-8")


_INCLUDE = re.compile(r'^[ \t]*#[ \t]*include[ \t]+"([A-Za-z0-9_.-]+\.glsl)"[ \t]*$', re.MULTILINE)


def shader_source(name: str) -> str:
    """The text of ``shaders/NAME.glsl`` with its ``#include "FILE.glsl"``
    lines replaced by shaders/FILE.glsl (an include file has no #version
    line; each file is included once per program, nested includes allowed).
    ``#line`` directives keep the compiler's line numbers those of each
    file: source string 0 is NAME.glsl, string k the k-th included file."""
    included: list[str] = []

    def expand(text: str, string: int) -> str:
        out, at = [], 0
        for match in _INCLUDE.finditer(text):
            filename = match.group(1)
            out.append(text[at : match.start()])
            at = match.end()
            if filename in included:
                continue
            included.append(filename)
            line_after = text.count("\n", 0, match.end()) + 2  # GLSL numbers lines from 1
            out.append(
                f"#line 1 {len(included)}\n{expand(_shader_file(filename), len(included))}\n"
                f"#line {line_after - 1} {string}"
            )
        out.append(text[at:])
        return "".join(out)

    return expand(_shader_file(f"{name}.glsl"), 0)


def load_program(ctx: moderngl.Context, name: str, defines: tuple[str, ...] = ()) -> moderngl.Program:
    """Compile shaders/NAME.glsl: one file, stages split by #if defined X_SHADER;
    each of defines (names) is #defined too, for variants of one program."""
    source = shader_source(name)
    version, _, body = source.partition("\n")
    extra = "".join(f"#define {d}\n" for d in defines)

    def stage(define: str) -> str:
        return f"{version}\n#define {define}\n{extra}#line 2\n{body}"  # the compiler's line numbers: the file's

    return ctx.program(vertex_shader=stage("VERTEX_SHADER"), fragment_shader=stage("FRAGMENT_SHADER"))


def load_compute(ctx: moderngl.Context, name: str, defines: tuple[str, ...] = ()) -> moderngl.ComputeShader:
    """Compile shaders/NAME.glsl as a compute shader (COMPUTE_SHADER and
    each of defines #defined), as load_program does for drawing programs."""
    version, _, body = shader_source(name).partition("\n")
    extra = "".join(f"#define {d}\n" for d in defines)
    return ctx.compute_shader(f"{version}\n#define COMPUTE_SHADER\n{extra}#line 2\n{body}")


@dataclass(frozen=True)
class Capabilities:
    """What a context offers: version (e.g. 450), its GL_VERSION and GL_RENDERER
    strings, compute shaders, float64 in shaders (GL_ARB_gpu_shader_fp64), and
    whether it is a hardware context (not Mesa's llvmpipe, softpipe or swrast)."""

    version: int
    version_string: str
    renderer: str
    compute: bool
    fp64: bool
    hardware: bool

    @property
    def missing(self) -> list[str]:
        """What the GPU solve needs and this context lacks, in words ([]: nothing)."""
        out = []
        if self.version < GL_COMPUTE_VERSION:
            out.append(f"OpenGL 4.5 (the context is {self.version // 100}.{self.version % 100 // 10})")
        if not self.compute:
            out.append("compute shaders")
        if not self.fp64:
            out.append("float64 in shaders (GL_ARB_gpu_shader_fp64)")
        return out


SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "software rasterizer")


def capabilities(ctx: moderngl.Context) -> Capabilities:
    """Probe ctx (cheap: strings and the extension list)."""
    version = int(ctx.version_code)
    extensions = ctx.extensions
    renderer = str(ctx.info.get("GL_RENDERER", ""))
    return Capabilities(
        version=version,
        version_string=str(ctx.info.get("GL_VERSION", "")),
        renderer=renderer,
        compute=version >= 430 or "GL_ARB_compute_shader" in extensions,
        fp64=version >= 400 or "GL_ARB_gpu_shader_fp64" in extensions,
        hardware=not any(word in renderer.lower() for word in SOFTWARE_RENDERERS),
    )


_headless: moderngl.Context | None = None


def headless_context() -> moderngl.Context:
    """The process's one standalone EGL context, created on first use."""
    global _headless
    if _headless is None:
        _headless = create_headless_context()
    return _headless


def program(ctx: moderngl.Context, name: str, defines: tuple[str, ...] = (), compute: bool = False):
    """The compiled program NAME (the variant with defines, as load_program;
    compute: a compute shader, load_compute), cached on the context
    (released with it)."""
    if not isinstance(ctx.extra, dict):
        ctx.extra = {}
    programs = ctx.extra.setdefault("bsrt_programs", {})
    key = (name, tuple(defines), compute) if defines or compute else name
    if key not in programs:
        programs[key] = (load_compute if compute else load_program)(ctx, name, tuple(defines))
    return programs[key]


def keep(ctx: moderngl.Context, key, make, limit: int = 1):
    """make() once per key, kept on ctx for later calls (framebuffers reused
    by renders of one size, buffers by calls of one size); key: a tuple whose
    first item names its family, of which the least recently used beyond
    limit keys is released before a new one is made. The object needs a
    release() method; release_cached releases them all."""
    if not isinstance(ctx.extra, dict):
        ctx.extra = {}
    kept = ctx.extra.setdefault("bsrt_kept", {})
    if key in kept:
        kept[key] = kept.pop(key)  # now the most recently used
        return kept[key]
    while (family := [k for k in kept if k[0] == key[0]]) and len(family) >= limit:
        bind_default_framebuffer(ctx)  # the one to release may be bound
        kept.pop(family[0]).release()
    kept[key] = made = make()
    return made


def bind_default_framebuffer(ctx: moderngl.Context) -> None:
    """Bind framebuffer 0 (the window, or none headless).

    Call before releasing a bound framebuffer: moderngl otherwise keeps the
    released one as current and the next framebuffer creation fails with
    GL_INVALID_OPERATION.
    """
    if not isinstance(ctx.extra, dict):
        ctx.extra = {}
    if "bsrt_default_fbo" not in ctx.extra:
        ctx.extra["bsrt_default_fbo"] = ctx.detect_framebuffer(0)
    ctx.extra["bsrt_default_fbo"].use()


def create_window_context() -> moderngl.Context:
    """A moderngl context for the OpenGL context current on this thread (the
    preview's glfw window, which owns it). GLX first, then EGL. Raises
    RenderError when the window's context cannot be used (not 3.3 core)."""
    errors = []
    for backend in (None, "egl"):
        try:
            if backend is None:
                return moderngl.create_context(require=GL_VERSION)
            return moderngl.create_context(require=GL_VERSION, backend=backend)
        except Exception as exc:  # glcontext raises plain Exception subclasses
            errors.append(f"{backend or 'default'}: {exc}")
    raise RenderError("cannot use the window's OpenGL context (" + "; ".join(errors) + "); " + FIX_HINT)


def release_cached(ctx: moderngl.Context) -> int:
    """Release the programs :func:`program` and the objects :func:`keep`
    cached on ctx. Call it before releasing a window's context: that GL
    context belongs to glfw, so releasing the moderngl wrapper frees
    nothing. Returns how many."""
    if not isinstance(ctx.extra, dict):
        return 0
    objects = list(ctx.extra.pop("bsrt_programs", {}).values()) + list(ctx.extra.pop("bsrt_kept", {}).values())
    if "bsrt_gpu_patches" in ctx.extra:  # rendering/gpu.py's patch table
        objects.append(ctx.extra.pop("bsrt_gpu_patches"))
    if objects:
        bind_default_framebuffer(ctx)  # a kept framebuffer may be bound
    for obj in objects:
        obj.release()
    ctx.extra.pop("bsrt_default_fbo", None)
    return len(objects)


def max_framebuffer_side(ctx: moderngl.Context) -> int:
    """The largest square framebuffer the context draws into at once: the
    least of its texture, renderbuffer and viewport limits (llvmpipe: 16384)."""
    info = ctx.info
    limits = [info.get("GL_MAX_TEXTURE_SIZE"), info.get("GL_MAX_RENDERBUFFER_SIZE")]
    viewport = info.get("GL_MAX_VIEWPORT_DIMS")
    if viewport:
        limits += list(viewport)
    return int(min(x for x in limits if x))

"""The GPU path: the seeded root finder as an OpenGL compute shader in float64.

``choose_device`` turns the ``device`` setting ("auto", "cpu", "gpu") and a
context into the device that runs the solve; ``find_roots_gpu`` is
:func:`bsrt.rendering.solve.find_roots` run by ``shaders/solve.glsl`` (the
same loop as ``kernels/roots.py``, the reference) on the patch table
uploaded as storage buffers (``shaders/patches.glsl``), the trims tested
there too in float64 (``shaders/trim64.glsl``, a port of
``kernels/trim.py``'s point_kept); the items the GPU does not settle go on
to the CPU repair exactly as the CPU solve's do (rendering/trace.py,
hard_pixels.py).
"""

from __future__ import annotations

import dataclasses

import moderngl
import numpy as np

from bsrt import interrupts
from bsrt.errors import InputError, RenderError
from bsrt.geometry.patches import PatchSet
from bsrt.kernels.method_ids import FAST, GRADIENT, NEWTON
from bsrt.kernels.prelim import gather_roots
from bsrt.kernels.roots import MAX_HALVINGS, STALL_STEPS
from bsrt.kernels.threads import run_chunks
from bsrt.methods import REFERENCE_METHOD
from bsrt.rendering import gl
from bsrt.rendering.solve import Rays, RootResult, seeded_kernel_id
from bsrt.settings import DEVICES

GROUP = 64  # invocations per workgroup (local_size_x, #defined GROUP) on a hardware context: group_size
SLICE = 64 * 4096  # items per dispatch at most (at most 65535 groups on every OpenGL 4.3+ context; 32 MiB of
# buffers): SIGINT and SIGTERM are acted on between dispatches (bsrt.interrupts), a fraction of a second
DEFINES = (
    f"GRADIENT {GRADIENT}",
    f"FAST {FAST}",
    f"NEWTON {NEWTON}",
    f"MAX_HALVINGS {MAX_HALVINGS}",
    f"STALL_STEPS {STALL_STEPS}",
)
REAL_ARRAYS = ("coef", "bounds", "inv_size", "domain", "breaks_u", "breaks_v")
INT_ARRAYS = ("coef_start", "degree", "dim", "break_start_u", "break_start_v", "grid_start", "patch_grid")
TRIM_REAL_ARRAYS = ("band_v0", "band_scale", "coef", "ends", "entry_box")  # kernels/trim.py's TrimTable
TRIM_INT_ARRAYS = ("trimmed", "band_first", "band_count", "degree", "band_start", "entry_piece")


def group_size(ctx: moderngl.Context) -> int:
    """Invocations per workgroup on ctx (current): GROUP, or 1 on a software renderer.

    Mesa 22's llvmpipe runs a workgroup's invocations as the lanes of SIMD
    vectors, and where they leave a loop at different turns it mixed them
    up: measured, a shadow ray's walk skipped a node, a loop over the lights
    skipped a light, a loop of squarings gave another lane's power, on a few
    hits in ten thousand (the same hits alone, or in workgroups of one, gave
    the kernels' answers). One invocation per workgroup costs llvmpipe its
    SIMD width (about 3x slower there); a GPU runs workgroups of GROUP. (llvmpipe
    pads a workgroup to its SIMD width with invocations whose local index is
    past local_size_x; each shader returns at once in those, else they ran
    the walks on stray data, 20 ms an invocation.)"""
    if not isinstance(ctx.extra, dict):
        ctx.extra = {}
    if "bsrt_group" not in ctx.extra:  # (ctx is current: entering it again here would leave none current)
        ctx.extra["bsrt_group"] = GROUP if gl.capabilities(ctx).hardware else 1
    return ctx.extra["bsrt_group"]


def compute_defines(ctx: moderngl.Context, *extra: str) -> tuple[str, ...]:
    """The #defines of a compute shader on ctx: the kernels' constants, the workgroup size GROUP, extra."""
    return DEFINES + (f"GROUP {group_size(ctx)}",) + extra


def dispatch_size(ctx: moderngl.Context) -> int:
    """Items per dispatch on ctx: SLICE, or fewer where 65535 workgroups (every OpenGL 4.3+ context's
    limit) hold fewer."""
    return min(SLICE, 65535 * group_size(ctx))


def run(ctx: moderngl.Context, shader, count: int) -> None:
    """Dispatch shader over count items (at most dispatch_size(ctx)) in workgroups of group_size(ctx)."""
    shader.run(group_x=-(-count // group_size(ctx)))


def compute_context(ctx=None) -> moderngl.Context:
    """The context that runs compute shaders: ctx when it is a moderngl
    context (the map's), else the process's headless one (the preview's
    solver process has no map context)."""
    return ctx if isinstance(ctx, moderngl.Context) else gl.headless_context()


def choose_device(setting: str, ctx=None) -> tuple[str, moderngl.Context | None]:
    """(device, context) for the ``device`` setting: ("cpu", None) or ("gpu", a context).

    auto and cpu: the CPU kernels. auto takes the faster path, and that is the
    CPU on every machine measured: on llvmpipe the kernels are as fast, and on
    an NVIDIA H200 beside 16 cores (2026-11-26, docs/performance.md) whole
    renders on the GPU path took 4-7x the CPU's (then the any-hit walks
    copied Bezier nets into per-invocation arrays, since changed and not yet
    measured there). gpu: the
    compute shaders on any context that has them (llvmpipe included), else an
    InputError naming what the context lacks."""
    if setting not in DEVICES:
        raise InputError(f"render.device: expected one of {', '.join(DEVICES)}, got {setting!r}")
    if setting in ("cpu", "auto"):
        return "cpu", None
    context = compute_context(ctx)
    with context:  # current on this thread while probed
        caps = gl.capabilities(context)
    if caps.missing:
        raise InputError(_missing_message(caps))
    return "gpu", context


def hardware_gpu() -> bool:
    """Whether this process's headless context is a hardware one that runs the GPU path
    (OpenGL 4.5, compute shaders, float64): where bsrt bench times both devices by default."""
    try:
        context = gl.headless_context()
    except RenderError:
        return False
    with context:
        caps = gl.capabilities(context)
    return caps.hardware and not caps.missing


def check_gpu() -> None:
    """Raise choose_device("gpu")'s InputError if this machine's headless
    context cannot run the GPU solve, probed in a child process: for a
    process that will open a window (the preview), where a standalone EGL
    context, even released again, stops the window's GLX one."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        message = pool.submit(_probe_message).result()
    if message:
        raise InputError(message)


def _probe_message() -> str:
    """check_gpu's child: "" when the GPU solve can run here, else the error message."""
    caps = gl.capabilities(gl.headless_context())
    return _missing_message(caps) if caps.missing else ""


def _missing_message(caps: gl.Capabilities) -> str:
    return (
        f"render.device: gpu needs {', '.join(caps.missing)}, which the OpenGL context "
        f'({caps.renderer}, {caps.version_string}) lacks; use device = "cpu" or "auto"'
    )


def pack_patches(patches: PatchSet) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """The patch table (and, for a trimmed scene, its trim table, the names
    prefixed "trim_") as shaders/patches.glsl and trim64.glsl read them:
    (reals (R,) float64, ints (I,) int32, offsets name -> first element of
    that array; "trim_coef_rows": the trim pieces' largest degree + 1)."""
    tables = [(patches.arrays, "", REAL_ARRAYS, INT_ARRAYS)]
    offsets = {}
    if patches.trimmed:
        tables.append((patches.trims, "trim_", TRIM_REAL_ARRAYS, TRIM_INT_ARRAYS))
        offsets["trim_coef_rows"] = int(patches.trims.coef.shape[1])
    return pack_tables(tables, offsets)


def pack_tables(tables, offsets: dict[str, int]) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """(reals (R,) float64, ints (I,) int32, offsets) of tables: (table, prefix,
    real names, int names) each, every named array of the table flattened in
    order into reals or ints, offsets[prefix + name] its first element (added
    to the offsets given)."""
    reals, ints = [], []
    real_at = int_at = 0
    for table, prefix, real_names, int_names in tables:
        for name in real_names:
            a = np.ascontiguousarray(getattr(table, name), dtype=np.float64).ravel()
            offsets[prefix + name], real_at = real_at, real_at + a.size
            reals.append(a)
        for name in int_names:
            a = np.asarray(getattr(table, name)).ravel().astype(np.int64)
            if a.size and (a.max() > np.iinfo(np.int32).max or a.min() < np.iinfo(np.int32).min):
                raise InputError(f'the scene is too large for the GPU path ({prefix}{name}); use device = "cpu"')
            offsets[prefix + name], int_at = int_at, int_at + a.size
            ints.append(a.astype(np.int32))
    if max(real_at, int_at) > np.iinfo(np.int32).max:
        raise InputError('the scene is too large for the GPU path (offsets beyond int32); use device = "cpu"')
    reals.append(np.zeros(1))  # never an empty buffer
    ints.append(np.zeros(1, dtype=np.int32))
    return np.concatenate(reals), np.concatenate(ints), offsets


class Uploaded:
    """A packed table (pack_tables' reals, ints, offsets) of source in two
    storage buffers on ctx; what: its name in the error when too large.
    dependents: tables of the same source's other parts (the hierarchy of
    these patches: gpu_shade.py), released with it."""

    def __init__(self, ctx: moderngl.Context, source, packed, what: str):
        reals, ints, self.offsets = packed
        limit = int(ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE") or 0)
        if limit and max(reals.nbytes, ints.nbytes) > limit:
            raise InputError(
                f"render.device: the scene's {what} ({reals.nbytes / 2**20:.0f} MiB) is larger than the "
                f'OpenGL context\'s storage buffers hold ({limit / 2**20:.0f} MiB); use device = "cpu"'
            )
        self.source, self.dependents = source, {}
        self.reals = ctx.buffer(reals.tobytes())
        try:
            self.ints = ctx.buffer(ints.tobytes())
        except BaseException:
            self.reals.release()
            raise

    def release(self) -> None:
        self.reals.release()
        self.ints.release()
        for table in self.dependents.values():
            table.release()
        self.dependents = {}


class KeptBuffers:
    """Storage buffers on ctx, one of each of the given sizes in bytes (for kept_buffers)."""

    def __init__(self, ctx: moderngl.Context, sizes: tuple[int, ...]):
        self.buffers = []
        try:
            for size in sizes:
                self.buffers.append(ctx.buffer(reserve=max(size, 4)))
        except BaseException:
            self.release()
            raise

    def release(self) -> None:
        for buffer in self.buffers:
            buffer.release()
        self.buffers = []


def kept_buffers(ctx: moderngl.Context, family: str, items: int, bytes_per_item: tuple[int, ...]) -> list:
    """Storage buffers for at least ``items`` items, bytes_per_item[k] bytes an item in buffer k, kept
    on ctx for the next call of the same family (gl.keep; one set a family): a call of a size the kept
    set holds reuses it, a larger one replaces it (its items rounded up to an eighth of a power of
    two: at most 1/8 unused, at least 1,024). Every compute shader's per-call buffers come from here:
    created each time, they cost llvmpipe 0.5 ms a buffer, 19 ms of a 384x384 render. Their
    contents are what the last call left; gl.release_cached releases them with the context's
    other kept objects."""
    grain = 1 << max(7, (max(items, 1) - 1).bit_length() - 3)
    capacity = max(1024, -(-items // grain) * grain)
    if not isinstance(ctx.extra, dict):
        ctx.extra = {}
    kept = [k for k in ctx.extra.get("bsrt_kept", {}) if k[0] == family and k[2] == bytes_per_item]
    if kept and kept[-1][1] >= items:  # a set that holds them
        capacity = kept[-1][1]
    sizes = tuple(capacity * b for b in bytes_per_item)
    return gl.keep(ctx, (family, capacity, bytes_per_item), lambda: KeptBuffers(ctx, sizes)).buffers


def uploaded(ctx: moderngl.Context, patches: PatchSet) -> Uploaded:
    """The patch table of patches on ctx, uploaded once per PatchSet (the last
    one is kept on the context; gl.release_cached releases it)."""
    if not isinstance(ctx.extra, dict):
        ctx.extra = {}
    kept = ctx.extra.get("bsrt_gpu_patches")
    if kept is not None and kept.source is patches:
        return kept
    if kept is not None:
        kept.release()
        ctx.extra.pop("bsrt_gpu_patches")
    ctx.extra["bsrt_gpu_patches"] = made = Uploaded(ctx, patches, pack_patches(patches), "patch table")
    return made


def find_roots_gpu(
    ctx: moderngl.Context,
    patches: PatchSet,
    rays: Rays,
    ray: np.ndarray,
    surface: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    method: str = REFERENCE_METHOD,
    tolerance: float = 1e-9,
    max_iterations: int = 64,
    stop_on_growth: bool = False,
) -> RootResult:
    """find_roots (same arguments and result: M items, ray (M,) int into
    rays, surface (M,) int, u, v (M,) float64 starts) solved by
    shaders/solve.glsl on ctx (a context with OpenGL 4.5 and float64:
    choose_device), the trims applied there too (trim64.glsl)."""
    kernel_id = seeded_kernel_id(method)
    m = int(np.shape(ray)[0])
    out = RootResult.empty(m)
    if m == 0:
        return out
    ray = np.asarray(ray, dtype=np.int64)
    surface = np.asarray(surface)
    with ctx:  # current on this thread for the duration
        shader = solver(ctx, "solve", patches, kernel_id, tolerance, max_iterations, stop_on_growth)
        step = dispatch_size(ctx)
        for first in range(0, m, step):  # buffers of one slice at a time: bounded, whatever m
            _solve_slice(ctx, shader, rays, ray, surface, u, v, slice(first, min(m, first + step)), out)
            interrupts.safe_point()  # this slice done: a waiting signal is taken between slices
    return out


def solver(ctx, name: str, patches: PatchSet, kernel_id: int, tolerance, max_iterations, stop_on_growth):
    """The compute shader NAME (one that includes solve_core.glsl) ready to
    dispatch on ctx (current): compiled with the kernels' constants (and the
    trim test for a trimmed scene), the patch table uploaded (once per
    PatchSet) and bound to storage buffers 0 and 1, the solve's uniforms set."""
    shader = gl.program(ctx, name, compute_defines(ctx, *(("TRIM_TEST",) if patches.trimmed else ())), compute=True)
    bind_patch_table(ctx, shader, patches)
    set_uniform(shader, "method", kernel_id)
    set_uniform(shader, "max_iterations", int(max_iterations))
    set_uniform(shader, "stop_on_growth", int(bool(stop_on_growth)))
    set_uniform(shader, "tol2", float(tolerance) * float(tolerance))
    return shader


def bind_patch_table(ctx, shader, patches: PatchSet) -> None:
    """patches' table (patches.glsl, trim64.glsl) on ctx (current), uploaded
    once per PatchSet, bound to storage buffers 0 and 1, its offsets set on shader."""
    table = uploaded(ctx, patches)
    for key, offset in table.offsets.items():
        set_uniform(shader, key if key == "trim_coef_rows" else f"off_{key}", offset)
    table.reals.bind_to_storage_buffer(0)
    table.ints.bind_to_storage_buffer(1)


def _solve_slice(ctx, shader, rays: Rays, ray, surface, u, v, part: slice, out: RootResult) -> None:
    """Items part of find_roots_gpu's (ray, surface, u, v) (M,) through the shader, into out."""
    n = part.stop - part.start
    items = np.empty((n, 8))
    items[:, 0:3] = rays.origin[ray[part]]
    items[:, 3:6] = rays.direction[ray[part]]
    items[:, 6] = u[part]
    items[:, 7] = v[part]
    set_uniform(shader, "item_count", n)
    buffers = kept_buffers(ctx, "bsrt_solve", n, (8 * 8, 4, 4 * 8, 4 * 4))  # items, surfaces, root reals, ints
    buffers[0].write(items)
    buffers[1].write(np.ascontiguousarray(surface[part], dtype=np.int32))
    for binding, buffer in enumerate(buffers, start=2):
        buffer.bind_to_storage_buffer(binding)
    run(ctx, shader, n)
    reals, ints = read_array(buffers[2], (n, 4), np.float64), read_array(buffers[3], (n, 4), np.int32)
    roots = decode_roots(reals, ints, np.arange(n))
    for field in dataclasses.fields(RootResult):
        getattr(out, field.name)[part] = getattr(roots, field.name)


def decode_roots(reals: np.ndarray, ints: np.ndarray, items: np.ndarray) -> RootResult:
    """The RootResult of items (M,) int64 (indices into N) from solve_core.glsl's root buffers
    (solve_into) read back: reals (N, 4) float64 (u, v, t, residual), ints (N, 4) int32
    (converged, patch, iterations, trimmed)."""
    out = RootResult.empty(items.size)  # every field written by gather_roots
    run_chunks(gather_roots, items.size, items, reals, ints, *(getattr(out, f.name) for f in dataclasses.fields(out)))
    return out


def read_array(buffer: moderngl.Buffer, shape: tuple[int, ...], dtype, offset: int = 0) -> np.ndarray:
    """Bytes of buffer from offset as a new array of shape and dtype (read straight into it)."""
    return read_rows(buffer, np.empty(shape, dtype=dtype), offset)


def read_rows(buffer: moderngl.Buffer, out: np.ndarray, offset: int = 0) -> np.ndarray:
    """Bytes of buffer from offset into the array out, in its own dtype and shape (straight into it
    where it is contiguous); returns out."""
    if out.flags.c_contiguous and out.flags.writeable:
        buffer.read_into(out, size=out.nbytes, offset=offset)
    else:
        out[...] = np.frombuffer(buffer.read(size=out.nbytes, offset=offset), dtype=out.dtype).reshape(out.shape)
    return out


def set_uniform(shader, name: str, value) -> None:
    """Set a uniform the compiler kept (an unused one is optimised away)."""
    try:
        shader[name].value = value
    except KeyError:
        pass


def kept_gpu(ctx: moderngl.Context, patches: PatchSet, surface, u, v) -> np.ndarray:
    """(N,) bool: shaders/trim64.glsl's answer (the GPU solve's trim test) for
    each (surface[i], u[i], v[i]) (surface: (N,) int, u, v: (N,) float64);
    what kernels.trim.kept_many answers on the CPU. ctx: a context with
    OpenGL 4.5 and float64 (choose_device)."""
    surface, u, v = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a)).ravel() for a in (surface, u, v)))
    n = u.size
    if n == 0 or not patches.trimmed:
        return np.ones(n, dtype=bool)
    points = np.stack([surface.astype(np.float64), u, v], axis=1)
    with ctx:
        shader = gl.program(ctx, "trim_probe64", compute_defines(ctx), compute=True)
        bind_patch_table(ctx, shader, patches)
        set_uniform(shader, "point_count", n)
        buffers = [ctx.buffer(points.tobytes())]
        try:
            buffers.append(ctx.buffer(reserve=4 * n))
            buffers[0].bind_to_storage_buffer(2)
            buffers[1].bind_to_storage_buffer(3)
            run(ctx, shader, n)  # tests' sizes: one dispatch
            return np.frombuffer(buffers[1].read(), dtype=np.int32) != 0
        finally:
            for buffer in buffers:
                buffer.release()

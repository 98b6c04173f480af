"""Shared fixtures. GL tests use a real headless context: if none can be
created the test fails (it is never skipped)."""

from __future__ import annotations

import functools
import hashlib
import os
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

from bsrt.rendering import gl

# The converted-model cache (bsrt/io/cache.py) of this test session: a fresh
# temporary folder, never the user's ~/.cache. Set at import, so the CLI's
# child processes inherit it; removed when the session ends.
_CACHE_DIR = tempfile.mkdtemp(prefix="bsrt-test-model-cache-")
os.environ["BSRT_CACHE_DIR"] = _CACHE_DIR


@pytest.fixture(scope="session", autouse=True)
def _model_cache_folder():
    yield _CACHE_DIR
    shutil.rmtree(_CACHE_DIR, ignore_errors=True)


MODELS = Path(__file__).resolve().parent / "data" / "models"
"""Third-party model files (IGES, STEP, .bez, .g2, .nurbs) kept in the repository
for the tests; MODELS / "SOURCES.md" says where each comes from, under which
licence, and its sha256."""


@functools.cache
def model_files() -> tuple[Path, ...]:
    """Every model file listed in MODELS/SOURCES.md, in its order.

    Checked first: each listed file exists with the listed sha256, and no
    other file sits beside them (licence texts, SOURCES.md and .gitattributes
    aside). A broken checkout fails the collection of the modules that use
    this, with one message naming every problem; it is never skipped."""
    table = (MODELS / "SOURCES.md").read_text(encoding="utf-8")
    listed = re.findall(r"^\| `([^`]+)` \|.*\| `([0-9a-f]{64})` \|$", table, re.MULTILINE)
    problems = []
    for name, digest in listed:
        path = MODELS / name
        if not path.is_file():
            problems.append(f"{name}: missing")
        elif hashlib.sha256(path.read_bytes()).hexdigest() != digest:
            problems.append(f"{name}: sha256 differs from SOURCES.md")
    names = {name for name, _ in listed}
    for path in sorted(MODELS.rglob("*")):
        rel = path.relative_to(MODELS)
        if (
            path.is_file()
            and rel.parts[0] != "LICENSES"
            and rel.name not in ("SOURCES.md", ".gitattributes")
            and rel.as_posix() not in names
        ):
            problems.append(f"{rel.as_posix()}: not listed in SOURCES.md")
    if problems or not listed:
        raise AssertionError(f"{MODELS}: " + ("; ".join(problems) or "SOURCES.md lists no files"))
    return tuple(MODELS / name for name, _ in listed)


@pytest.fixture(scope="session")
def ctx():
    """The process's headless EGL context (Mesa llvmpipe in CI)."""
    context = gl.headless_context()
    assert context.error == "GL_NO_ERROR"
    yield context
    assert context.error == "GL_NO_ERROR"


def scene_dict(
    surfaces,
    *,
    width=64,
    height=64,
    eye=(0.0, -4.0, 0.0),
    look_at=(0.0, 0.0, 0.0),
    up=(0.0, 0.0, 1.0),
    fov=40.0,
    method="newton",
    **render,
):
    """A minimal scene document (as tomllib would return it)."""
    return {
        "film": {"width": width, "height": height},
        "camera": {"eye": list(eye), "look_at": list(look_at), "up": list(up), "fov": fov},
        "render": {"method": method, **render},
        "light": [{"kind": "ambient", "intensity": 1.0}],
        "surface": surfaces,
    }


def flat_patch(x0=-1.0, x1=1.0, z0=-1.0, z1=1.0, y=0.0, degree=(1, 1), **extra):
    """A square in the plane y = const, as a [[surface]] table; u along x, v along z."""
    p, q = degree
    xs = np.linspace(x0, x1, p + 1)
    zs = np.linspace(z0, z1, q + 1)
    points = [[[float(x), y, float(z)] for z in zs] for x in xs]
    return {
        "degree": [p, q],
        "knots_u": [0.0] * (p + 1) + [1.0] * (p + 1),
        "knots_v": [0.0] * (q + 1) + [1.0] * (q + 1),
        "points": points,
        **extra,
    }


# ---------------------------------------------------------------- test tiers
#
# Markers (registered in pyproject.toml, --strict-markers; docs/testing.md):
#   gl      needs a real OpenGL context (EGL, Mesa llvmpipe), in this process or a child
#   window  opens a real window (Xvfb, GLX); every window test is also gl
#   cad     needs OpenCASCADE (the bsrt[cad] extra, OCP)
#   dask    needs Dask distributed (the bsrt[dask] extra)
#   slow    measured slow; `pytest -m "not slow"` is the fast tier
#
# gl, window, cad and dask are put on automatically here (pytest_collection_modifyitems)
# from what a test visibly needs, and by hand (@pytest.mark.gl / .cad) where it needs
# the part indirectly (bsrt.render rasterises its map with OpenGL; a STEP file is read
# through OpenCASCADE). The hand-put marks are checked while the tests run (_TierGuard):
# a test not marked gl that asks for an OpenGL context fails, and so does a test not
# marked cad that reads a file through OpenCASCADE. A child process of a test not
# marked gl (the CLI run by subprocess) finds no EGL device (BSRT_EGL_DEVICE points
# past the last), so it fails too instead of rendering unmarked.
#
# In CI (CI set and not 0/false, as .ci/run-like environments do) a skipped test is
# a failure: a missing part (no GL, no OCP, no Dask) must never pass quietly.

TIERS = ("gl", "window", "cad", "dask")
OCCT_SUFFIXES = (".step", ".stp", ".brep", ".brp")  # bsrt.io reads these only through OpenCASCADE
_NO_EGL_DEVICE = "4096"  # no machine has this many EGL devices: a child's context fails


def _module_needs(module) -> set[str]:
    """The parts a test module needs just to be imported: OCP (directly or through
    tests/occ_reference.py) means cad; dask or distributed means dask."""
    needs = set()
    for value in vars(module).values():
        name = getattr(value, "__module__", None) or getattr(value, "__name__", None) or ""
        if not isinstance(name, str):
            continue
        root = name.split(".")[0]
        if root in ("OCP", "occ_reference"):
            needs.add("cad")
        elif root in ("dask", "distributed"):
            needs.add("dask")
    return needs


# The slow tier: test ids (as pytest prints them) and the seconds each took, measured
# with `pytest --durations=0` on a 2-core machine with a warm numba cache (docs/testing.md).
# A whole test function is named without its [parameters]. A name that no longer
# matches any test of a module that was collected is an error, so a renamed test
# cannot drop out of the slow tier unnoticed.
SLOW: dict[str, float] = {
    "tests/test_animate.py::test_a_bad_keyframe_is_one_line_naming_file_and_key_exit_2": 44.1,  # 8 cases
    "tests/test_animate.py::test_animate_without_a_path_is_usage_error": 5.1,
    "tests/test_animate.py::test_keyframes_as_animated_png": 2.1,
    "tests/test_animate.py::test_orbit_of_8_frames_with_animated_webp": 88.1,
    "tests/test_api.py::test_to_toml_reads_back_to_the_same_scene[iges-trimmed]": 1.6,
    "tests/test_batch.py::test_a_killed_worker_does_not_lose_the_batch": 6.4,
    "tests/test_edges.py::test_the_box_edges_fall_on_the_pixels_its_visible_edges_cross_and_nowhere_else": 1.7,  # 2 cases
    "tests/test_edges.py::test_a_wider_edge_in_a_colour_covers_as_its_width_says": 1.1,
    "tests/test_fold.py::test_128_004_agrees_with_opencascade_away_from_edges": 1.5,
    "tests/test_film.py::test_a_streamed_render_gives_the_kept_render_s_image_and_stats": 5.6,  # load 11
    "tests/test_film.py::test_shadow_rays_block_exactly_where_the_any_hit_tracer_finds_an_occluder": 1.3,
    "tests/test_batch.py::test_bad_usage_exits_2": 5.6,
    "tests/test_batch.py::test_files_travel_with_the_task_to_a_scheduler": 7.1,
    "tests/test_batch.py::test_six_items_match_single_renders_and_one_failure_is_reported": 21.7,
    "tests/test_batch.py::test_without_dask_one_line_and_exit_2": 5.7,
    "tests/test_registries.py::test_doctor_lists_every_reader": 8.0,
    "tests/test_pictures.py::test_bsrt_scene_of_a_coloured_step_assembly_keeps_its_colours": 31.2,  # load 12
    "tests/test_bounded.py::test_a_film_wider_than_the_gl_limit_renders_through_tiles": 3.1,
    "tests/test_bounded.py::test_highest_degree_surface_renders_in_bounded_memory": 10.3,
    "tests/test_bounded.py::test_plane_of_degree_10_hits_every_pixel_at_the_closed_form_depth_in_bounded_memory": 5.5,
    "tests/test_bounded.py::test_spp_251_peaks_as_low_as_spp_64_and_averages_to_the_plane": 18.7,
    "tests/test_bvh.py::test_leaves_tile_and_cover_every_patch": 1.8,
    "tests/test_bvh.py::test_random_rays_match_exhaustive_search": 22.8,
    "tests/test_cache.py::test_an_unwritable_cache_folder_still_loads_with_one_note": 3.6,
    "tests/test_cache.py::test_second_load_of_a_real_step_part_comes_from_the_cache_and_is_equal": 3.0,
    "tests/test_cache.py::test_the_folder_is_kept_under_its_size_limit_least_recently_used_first": 1.3,
    "tests/test_cache.py::test_the_key_has_the_format": 2.5,
    "tests/test_cache.py::test_two_processes_loading_one_file_at_once_both_succeed": 41.7,
    "tests/test_cad_corpus.py::test_corpus_part_hits_agree_with_occt_away_from_edges": 20.1,  # 9 cases, 6 of them >= 1 s
    "tests/test_cad_corpus.py::test_corpus_part_loads_with_every_face_trimmed[step/occt/linkrods.step]": 1.1,
    "tests/test_cad_corpus.py::test_corpus_part_loads_with_every_face_trimmed[step/trimesh/box_sides.STEP]": 3.1,
    "tests/test_cli.py::test_console_script_runs_in_a_fresh_process": 6.0,
    "tests/test_cli.py::test_negative_vectors_in_a_fresh_process": 4.9,
    "tests/test_cli.py::test_overrides_and_map_command": 1.8,
    "tests/test_compile.py::test_every_kernel_compiles_exactly_one_signature_and_the_warm_up_all_of_them": 131.8,
    "tests/test_fuzz.py::test_each_model_reader_gives_a_valid_model_or_an_input_error_naming_the_file[.obj]": 1.1,
    "tests/test_fuzz.py::test_scene_documents_are_valid_or_refused_naming_the_file": 8.3,
    "tests/test_fuzz.py::test_short_cli_fuzz_pass_keeps_every_promise": 126.7,
    "tests/test_golden.py::test_golden_image[column-96-spp1-edges]": 2.6,
    "tests/test_golden.py::test_golden_image[water-lily-128-spp1-adaptive]": 2.2,
    "tests/test_gpu.py::test_device_gpu_renders_as_the_cpu[iges-trimmed]": 8.3,  # at load 9
    "tests/test_gpu.py::test_device_gpu_renders_as_the_cpu[column]": 3.0,
    "tests/test_gpu.py::test_device_gpu_renders_as_the_cpu[water-lily]": 1.2,
    "tests/test_gpu.py::test_device_gpu_renders_as_the_cpu[bench-64]": 1.2,
    "tests/test_gpu.py::test_stats_say_which_device_solved": 3.6,
    "tests/test_gpu.py::test_gpu_on_a_context_without_opengl_4_5_is_one_error_exit_2": 3.2,
    "tests/test_gpu.py::test_an_unknown_device_is_one_error": 2.8,
    "tests/test_gpu.py::test_plane_hits_are_exact": 1.4,  # the first compute shader compiled
    "tests/test_gpu_shadow.py::test_dispatch_slices_change_nothing": 1.4,
    "tests/test_gpu.py::test_batch_and_animate_refuse_gpu_without_opengl_4_5_before_any_item": 4.6,  # 2 cases
    "tests/test_preview.py::test_device_gpu_refines_to_the_cpu_render": 6.7,
    "tests/test_preview.py::test_device_gpu_without_opengl_4_5_exits_2_before_opening_a_window": 1.3,
    "tests/test_iges_occt_hits.py::test_shared_iges_hits_agree_with_opencascade_or_are_nearer_on_the_shape": 11.7,  # 2 cases
    "tests/test_intersect.py::test_sphere_nearest_hit_point_normal_and_parameters": 2.1,  # the first: loads the kernels
    "tests/test_intersect_cad.py::test_against_opencascade_on_a_trimmed_step_part": 4.0,
    "tests/test_intersect_cad.py::test_cylinder_trimmed_by_a_plane": 3.7,  # the first: loads the kernels
    "tests/test_intersect_cad.py::test_names_of_a_step_assembly_give_the_part_paths": 2.0,
    "tests/test_interrupts.py::test_scenes_with_a_control_point_at_1e9_render_40x40_and_count_rays_out_of_budget": 10.8,
    "tests/test_interrupts.py::test_sigterm_during_a_far_control_point_render_ends_it_within_a_second": 6.2,
    "tests/test_interrupts.py::test_sigterm_during_a_large_antialiased_column_ends_it_within_a_second": 16.1,
    "tests/test_map_trim.py::test_cad_parts_render_the_same_with_fewer_trimmed_roots": 5.5,  # 2 cases
    "tests/test_map_trim.py::test_the_per_fragment_trim_test_alone_renders_the_same[bearing.iges]": 3.2,
    "tests/test_models.py::test_every_model_file_renders_headless_or_is_refused[iges/occt/bearing.iges]": 3.5,
    "tests/test_models.py::test_every_model_file_renders_headless_or_is_refused[iges/overtureframework/asmo.igs]": 2.7,
    "tests/test_models.py::test_every_model_file_renders_headless_or_is_refused[step/occt/linkrods.step]": 1.9,
    "tests/test_models.py::test_every_model_file_renders_headless_or_is_refused[step/pythonocc-core/as1-oc-214.stp]": 1.8,
    "tests/test_models.py::test_every_model_file_renders_headless_or_is_refused[step/pythonocc-core/as1_pe_203.stp]": 2.1,
    "tests/test_models.py::test_every_model_file_renders_headless_or_is_refused[step/trimesh/box_sides.STEP]": 5.8,
    "tests/test_models.py::test_every_model_file_renders_headless_or_is_refused[step/trimesh/featuretype.STEP]": 1.3,
    "tests/test_occt.py::test_as1_assembly_has_every_face_in_place_with_colours": 13.4,
    "tests/test_occt.py::test_hits_agree_against_occt_intersector[sphere-cut-by-cylinder]": 1.4,
    "tests/test_occt.py::test_hits_agree_against_occt_intersector[as1-oc-214]": 3.3,
    "tests/test_occt.py::test_iges_through_occt_matches_step": 4.2,  # 2 cases
    "tests/test_occt.py::test_step_and_iges_through_bsrts_own_reader_render_the_same_hits[0]": 1.3,
    "tests/test_occt.py::test_third_party_iges_through_occt": 5.7,  # 2 cases
    "tests/test_occt_seams.py::test_full_torus_with_its_seam_edges": 4.4,  # 2 cases
    "tests/test_outputs.py::test_a_full_disk_is_one_message_naming_the_output_and_leaves_nothing": 1.4,
    "tests/test_outputs.py::test_a_legal_long_output_name_is_written": 1.6,
    "tests/test_outputs.py::test_a_usage_error_is_one_line": 3.0,  # 3 cases, 2 of them >= 1 s
    "tests/test_outputs.py::test_an_import_that_is_a_fifo_is_refused": 2.2,
    "tests/test_outputs.py::test_non_regular_inputs_are_refused_at_once": 15.9,  # 6 cases
    "tests/test_outputs.py::test_render_png_aov_and_stats_together": 1.1,
    "tests/test_outputs.py::test_stats_on_a_failing_stdout_leaves_no_image": 1.3,
    "tests/test_outputs.py::test_the_image_and_the_aovs_may_not_be_one_file": 4.7,
    "tests/test_outputs.py::test_the_output_may_not_be_a_file_the_scene_imports": 2.7,
    "tests/test_outputs.py::test_the_output_may_not_be_the_model_it_renders": 3.3,
    "tests/test_preview.py::test_bad_display_exits_2": 2.2,
    "tests/test_preview.py::test_bad_script_exits_2_before_opening_a_window": 1.0,
    "tests/test_preview.py::test_camera_overrides_and_format_like_bsrt_render": 12.3,
    "tests/test_preview.py::test_fast_view_draws_the_scene": 0.1,  # shares the scripted preview session
    "tests/test_preview.py::test_fast_view_frames_and_screenshot": 5.1,
    "tests/test_preview.py::test_fast_view_honours_trims": 8.2,
    "tests/test_preview.py::test_frame_log_records_refinement": 0.0,  # shares the scripted preview session
    "tests/test_preview.py::test_key_s_saves_next_to_the_scene": 0.0,  # shares the scripted preview session
    "tests/test_preview.py::test_martin_method_then_back_to_newton": 9.2,
    "tests/test_preview.py::test_method_switch_and_map": 0.5,  # shares the scripted preview session
    "tests/test_preview.py::test_no_display_exits_2_pointing_at_bsrt_render": 2.4,
    "tests/test_preview.py::test_refined_image_equals_render": 0.8,  # shares the scripted preview session
    "tests/test_preview.py::test_resize_renders_at_the_new_framebuffer_size": 9.7,
    "tests/test_preview.py::test_scripted_orbit_changes_the_image": 0.0,  # shares the scripted preview session
    "tests/test_preview.py::test_session_exits_cleanly": 9.8,
    "tests/test_preview.py::test_solver_abandons_a_stale_job_at_once": 8.7,
    "tests/test_preview_refine.py::test_bench_preview_without_a_display_is_refused_before_benchmarking": 2.1,
    "tests/test_preview_refine.py::test_coarse_then_exact_cancelled_by_a_resize_and_a_move_while_refining": 36.5,  # 28-36 s
    "tests/test_progress.py::test_a_failure_after_the_bar_started_gets_a_clean_line": 1.4,
    "tests/test_progress.py::test_no_progress_on_a_terminal": 1.4,
    "tests/test_progress.py::test_nothing_on_a_pipe": 1.4,
    "tests/test_progress.py::test_progress_with_aov_names_both_files": 1.2,
    "tests/test_progress.py::test_render_on_a_terminal_shows_the_bar_then_the_summary": 1.6,
    "tests/test_startup.py::test_a_cli_render_imports_no_opencascade_dask_window_or_preview": 11.6,
    "tests/test_startup.py::test_a_first_render_with_an_empty_cache_announces_the_compile_and_fills_the_cache": 185.8,
    "tests/test_startup.py::test_a_kernel_loaded_from_the_cache_runs_and_links_into_a_kernel_compiled_after_it": 2.2,
    "tests/test_startup.py::test_an_unwritable_cache_folder_still_renders": 262.6,
    "tests/test_startup.py::test_doctor_compile_fills_an_empty_cache": 146.2,
    "tests/test_startup.py::test_the_command_line_parser_imports_neither_numba_nor_any_extra": 1.5,
    "tests/test_render.py::test_bands_and_a_given_map_give_the_same_hits": 1.2,
    "tests/test_render.py::test_methods_agree_on_every_pixel": 2.9,  # 2 cases
    "tests/test_signals.py::test_a_signal_at_any_moment_leaves_all_outputs_or_none": 31.6,  # 3 cases
    "tests/test_signals.py::test_a_signal_during_bsrt_map_leaves_the_map_or_nothing": 8.6,
    "tests/test_signals.py::test_sigkill_at_any_moment_leaves_no_lone_output": 14.9,
    "tests/test_trim.py::test_a_closed_cubic_b_spline_with_interior_knots": 3.8,
    "tests/test_trim.py::test_a_star_polygon_against_exact_point_in_polygon": 4.2,
    "tests/test_trim_gl.py::test_glsl_trim_test_matches_the_kernels_on_bearing": 1.4,
    "tests/test_validation.py::test_a_chain_of_1500_iges_124_transforms_renders": 2.8,
    "tests/test_validation.py::test_a_scene_too_far_for_float64_names_the_eye": 2.0,
    "tests/test_validation.py::test_a_utf8_byte_order_mark_is_accepted_in_scene_and_model_files": 3.6,  # 2 cases
    "tests/test_validation.py::test_an_iges_124_loop_is_refused": 2.1,
    "tests/test_validation.py::test_automatic_camera_beyond_the_limit_names_the_model": 2.4,
    "tests/test_validation.py::test_bench_with_no_method_is_refused": 3.5,  # 2 cases
    "tests/test_validation.py::test_coordinate_near_1e308_is_refused": 2.1,
    "tests/test_validation.py::test_egl_device_index_that_is_not_a_number_is_refused": 2.2,
    "tests/test_validation.py::test_extreme_but_accepted_values_render_silently": 11.9,  # 5 cases
    "tests/test_validation.py::test_eye_at_1e300_names_the_eye_not_the_up_vector": 2.0,
    "tests/test_validation.py::test_fov_of_5e_324_is_refused": 1.9,
    "tests/test_validation.py::test_fov_override_below_the_limit_is_refused_for_a_model": 1.6,
    "tests/test_validation.py::test_iges_124_chain_overflowing_when_composed_is_refused": 1.8,
    "tests/test_validation.py::test_iges_124_entry_near_1e308_is_refused": 1.6,
    "tests/test_validation.py::test_iges_range_within_1e_9_past_the_knots_says_so": 1.7,
    "tests/test_validation.py::test_import_name_over_255_characters_is_refused": 1.9,
    "tests/test_validation.py::test_info_refuses_a_model_format_for_a_scene": 1.0,
    "tests/test_validation.py::test_map_command_checks_camera_overrides_too": 5.0,
    "tests/test_validation.py::test_render_refuses_a_model_format_for_a_scene": 1.8,
    "tests/test_validation.py::test_scale_near_1e308_is_refused": 1.9,
    "tests/test_validation.py::test_spp_beyond_int64_is_refused": 1.6,
    "tests/test_validation.py::test_surface_that_is_not_an_array_of_tables_names_the_file": 1.7,
    "tests/test_validation.py::test_tolerance_below_float64_is_refused_with_the_smallest_usable_value": 1.9,
    "tests/test_validation.py::test_toml_nested_50000_deep_is_refused": 1.3,
    "tests/test_validation.py::test_translation_that_moves_points_out_of_range_is_refused": 1.8,
    "tests/test_validation.py::test_unicode_digits_in_iges_are_refused": 2.4,
    "tests/test_validation.py::test_unicode_digits_in_model_files_are_refused": 6.8,  # 3 cases
    "tests/test_validation.py::test_weights_spanning_more_than_1e12_are_refused": 2.9,
    "tests/test_validation.py::test_width_beyond_int64_is_refused": 1.8,
    "tests/test_validation.py::test_wrong_types_in_scene_files_are_refused": 6.4,  # 4 cases
}


def _mark_slow(config, items) -> None:
    collected = {item.nodeid for item in items} | {item.nodeid.split("[")[0] for item in items}
    modules = {item.nodeid.split("::")[0] for item in items}
    whole = not config.option.keyword and all(os.path.isdir(arg) for arg in config.args)  # whole modules
    stale = [name for name in SLOW if name.split("::")[0] in modules and name not in collected]
    if stale and whole:
        raise pytest.UsageError("tests/conftest.py SLOW names tests that do not exist: " + ", ".join(stale))
    for item in items:
        if item.nodeid in SLOW or item.nodeid.split("[")[0] in SLOW:
            item.add_marker(pytest.mark.slow)


@pytest.hookimpl(tryfirst=True)  # before -m deselects by these marks
def pytest_collection_modifyitems(config, items):
    _mark_slow(config, items)
    cache: dict[object, set[str]] = {}
    for item in items:
        fixtures = set(getattr(item, "fixturenames", ()))
        module = getattr(item, "module", None)
        if module not in cache:
            cache[module] = _module_needs(module) if module is not None else set()
        needs = set(cache[module])
        if "display" in fixtures:  # tests/test_preview.py: a real X display (Xvfb)
            needs |= {"window", "gl"}
        if "ctx" in fixtures:  # the headless EGL context fixture above
            needs.add("gl")
        callspec = getattr(item, "callspec", None)  # a case over model files: STEP and BREP read through OCP
        if callspec is not None and any(
            isinstance(v, (str, os.PathLike)) and os.fspath(v).lower().endswith(OCCT_SUFFIXES)
            for v in callspec.params.values()
        ):
            needs.add("cad")
        for name in sorted(needs):
            if item.get_closest_marker(name) is None:
                item.add_marker(getattr(pytest.mark, name))


_MODULE_IMPORTS = {
    "cad": re.compile(r"^(import OCP|from OCP[ .]|from occ_reference |import occ_reference)", re.M),
    "dask": re.compile(r"^(import (dask|distributed)|from (dask|distributed)[ .])", re.M),
}
_PART_MODULES = {"cad": "OCP", "dask": "distributed"}


def pytest_ignore_collect(collection_path, config):
    """A module that imports a missing part (OCP, distributed) at its top is left out when
    -m deselects that part anyway (`pytest -m "not cad"` without the extra); otherwise its
    import error fails the run, as it must in CI."""
    markexpr = config.option.markexpr
    if not markexpr or collection_path.suffix != ".py" or not collection_path.name.startswith("test_"):
        return None
    import importlib.util

    from _pytest.mark.expression import Expression

    text = collection_path.read_text(encoding="utf-8")

    def missing(name: str) -> bool:
        try:
            return importlib.util.find_spec(name) is None
        except (ImportError, ValueError):  # sys.modules[name] = None: import blocked
            return True

    for part, pattern in _MODULE_IMPORTS.items():
        if (
            pattern.search(text)
            and missing(_PART_MODULES[part])
            and not Expression.compile(markexpr).evaluate(lambda name, **kw: name == part)
        ):
            return True
    return None


def _ci() -> bool:
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


class _TierGuard:
    """Fails a test that uses GL or OpenCASCADE without its marker (see above)."""

    def __init__(self):
        self.item = None
        self.used: set[str] = set()

    def note(self, part: str) -> None:
        item = self.item
        if item is None or item.get_closest_marker(part) is not None:
            return
        self.used.add(part)

    def install(self) -> None:
        import moderngl

        guard = self
        original_headless = gl.headless_context
        original_create = moderngl.create_context

        def headless_context(*args, **kwargs):
            guard.note("gl")
            return original_headless(*args, **kwargs)

        def create_context(*args, **kwargs):
            guard.note("gl")
            return original_create(*args, **kwargs)

        gl.headless_context = headless_context
        moderngl.create_context = create_context

        from bsrt.io import occt

        original_available, original_read = occt.available, occt.read

        def available(*args, **kwargs):
            guard.note("cad")
            return original_available(*args, **kwargs)

        def read(*args, **kwargs):
            guard.note("cad")
            return original_read(*args, **kwargs)

        occt.available, occt.read = available, read


_GUARD = _TierGuard()


def pytest_configure(config):
    _GUARD.install()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    _GUARD.item, _GUARD.used = item, set()
    saved = os.environ.get("BSRT_EGL_DEVICE")
    if item.get_closest_marker("gl") is None:
        os.environ["BSRT_EGL_DEVICE"] = _NO_EGL_DEVICE
    try:
        yield
    finally:
        if saved is None:
            os.environ.pop("BSRT_EGL_DEVICE", None)
        else:
            os.environ["BSRT_EGL_DEVICE"] = saved
        _GUARD.item = None


def _skip_fails_in_ci(report) -> None:
    if report.skipped and _ci() and not hasattr(report, "wasxfail"):
        report.outcome = "failed"
        report.longrepr = f"skipped in CI (CI={os.environ.get('CI')!r}), which runs every tier: {report.longrepr}"


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    outcome = yield
    _skip_fails_in_ci(outcome.get_result())  # pytest.importorskip at a module's top


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    _skip_fails_in_ci(report)
    if call.when != "call" or not _GUARD.used:
        return
    parts = sorted(_GUARD.used)
    record = os.environ.get("BSRT_TIER_RECORD")
    if record:  # finding which tests need a mark: list them, fail none
        with open(record, "a", encoding="utf-8") as out:
            out.write(f"{item.nodeid}\t{' '.join(parts)}\n")
        return
    message = (
        f"{item.nodeid} uses {' and '.join(parts)} but is not marked so: add "
        + ", ".join(f"@pytest.mark.{p}" for p in parts)
        + " (tests/conftest.py, docs/testing.md)"
    )
    if report.passed:
        report.outcome, report.longrepr = "failed", message
    else:
        report.sections.append(("tier marks", message))

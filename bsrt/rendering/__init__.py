"""Rendering: from a checked scene and its options to pixels and hits.

- options.py: ``RenderOptions``, the settings of one render, resolved once;
- pipeline.py: the one pipeline (``render``), bands, shading, secondary rays;
- prelim.py, map_mesh.py, gl.py, trim_gl.py: the preliminary map (OpenGL);
- trace.py: the tracing seam (the map-seeded tracer or the hierarchy);
- solve.py, hard_pixels.py, bvh.py, hits.py: root finding, suspect pixels,
  the hierarchy, the one hit record;
- shade.py, image.py, stats.py: shading, image files, timings;
- warm_up.py, bench.py: compiling the kernels up front, the paper's tables.
"""

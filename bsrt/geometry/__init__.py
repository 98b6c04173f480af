"""Geometry: B-spline surfaces and their trims, as data, in NumPy.

- basis.py: one-direction basics (spans, basis functions, knot insertion,
  a span's Bezier extraction matrices);
- bspline.py: the surface, its checks, the reference evaluator (the tests'
  judge) and Bezier extraction;
- trim.py: the one curve type (trim curves and the readers' curves) with its
  evaluator, trim loops and their checks;
- trim_table.py: the table the compiled trim test reads;
- patches.py: the patch table the kernels evaluate.

Imports nothing of bsrt above ``kernels``, ``errors``.
"""

"""Geometry: B-spline surfaces and their trims, as data, in NumPy.

- basis.py: one-direction basics (spans, basis functions, knot insertion);
- bspline.py: the surface, its checks, the reference evaluator (the tests'
  judge) and Bezier extraction;
- trim.py: trim curves and loops, their checks and the table the trim test reads;
- patches.py: the patch table the kernels evaluate.

Imports nothing of bsrt above ``kernels``, ``errors``.
"""

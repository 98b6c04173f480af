"""Many renders on Dask: ``bsrt.batch`` and ``bsrt.animate``.

- api.py: the Python functions ``batch`` and ``animate`` and the cluster;
- engine.py: inputs, output names, the task that travels with its files,
  atomic outputs, resume, the summary;
- animation.py: orbit and keyframe cameras, the animated file.
"""

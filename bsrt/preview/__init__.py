"""``bsrt preview``: an interactive window, a fast GL view while the camera
moves, then the exact image. One module per concern:

- app.py: the application and its frame loop; ``run`` (bsrt/cli/__init__.py parses the command line)
- window.py: the glfw window, input callbacks -> named events
- bindings.py: key names -> actions (data)
- view.py: the fast GL view, textures, screenshots
- refine.py: the refinement state machine (levels, bands, stale results)
- solver.py: the solver processes and their job protocol
- script.py: ``--events`` / ``--script``
"""

from bsrt.preview.app import Preview, WindowOptions, run, script_commands

__all__ = ["Preview", "WindowOptions", "run", "script_commands"]

"""The preview's input bindings, as data: key name -> (action, arguments).
The window module names the keys (``window.KEY_NAMES``); the application
runs the actions (``Preview.press``); the script's ``key NAME`` uses the
same names.
"""

from __future__ import annotations

from bsrt.methods import METHODS

ORBIT_DEGREES_PER_PIXEL = 0.4  # mouse drag, screen coordinates
KEY_ORBIT_DEGREES = 10.0
KEY_PAN_FRACTION = 0.05  # of the view height
ZOOM_STEP = 0.9  # distance factor per wheel notch or '+' press

BINDINGS = {
    "q": ("quit",),
    "escape": ("quit",),
    "m": ("toggle_map",),
    **{str(k): ("method", name) for k, name in enumerate(METHODS, start=1)},
    "s": ("save",),
    "c": ("print_camera",),
    "r": ("reset",),
    "plus": ("zoom", ZOOM_STEP),
    "minus": ("zoom", 1.0 / ZOOM_STEP),
    "left": ("orbit", -KEY_ORBIT_DEGREES, 0.0),
    "right": ("orbit", KEY_ORBIT_DEGREES, 0.0),
    "up": ("orbit", 0.0, KEY_ORBIT_DEGREES),
    "down": ("orbit", 0.0, -KEY_ORBIT_DEGREES),
    "shift+left": ("pan", -KEY_PAN_FRACTION, 0.0),
    "shift+right": ("pan", KEY_PAN_FRACTION, 0.0),
    "shift+up": ("pan", 0.0, KEY_PAN_FRACTION),
    "shift+down": ("pan", 0.0, -KEY_PAN_FRACTION),
}

KEYS_HELP = """\
mouse: left drag orbits, right or middle drag pans, the wheel zooms
keys:  arrows orbit (Shift+arrows pan), +/- zoom, M the preliminary map,
       1-{n} method ({names}), S save the exact image
       next to the scene, C print the camera as a [camera] table,
       R reset the camera, Esc/Q quit
""".format(n=len(METHODS), names=", ".join(METHODS))

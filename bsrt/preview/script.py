"""The preview's scripting: ``--events "orbit 30 0; wait; save out.png; quit"``
or ``--script FILE`` (one command a line or ';'-separated, '#' comments).
:func:`parse_script` checks a whole script before the window opens;
:func:`advance` runs it frame by frame against the application.
"""

from __future__ import annotations

import shlex
import time
from dataclasses import dataclass
from pathlib import Path

from bsrt.errors import InputError, RenderError
from bsrt.methods import METHODS
from bsrt.preview.bindings import BINDINGS
from bsrt.scene.camera import orbit, pan, zoom
from bsrt.scene.document import camera_toml

RESIZE_SECONDS = 5.0  # how long ``resize`` waits for the window to take the size

SCRIPT_HELP = """\
script commands (';' or newline separated, '#' starts a comment):
  orbit DYAW DPITCH [FRAMES]  orbit by degrees (spread over FRAMES frames, default 1)
  pan DX DY [FRAMES]          move the scene by DX, DY view heights (right, up)
  zoom FACTOR [FRAMES]        multiply the eye's distance to look_at by FACTOR
  key NAME                    press a key: m, s, c, r, 1-{n}, q, left, right, up, down, plus, minus
  method NAME                 switch the method ({names})
  resize W H                  resize the window (screen coordinates), until it has that size
  wait                        until the exact full-resolution image (or its failure)
  frames N                    let N frames pass
  sleep SECONDS               let time pass
  save FILE.png               wait, then write the exact image
  screenshot FILE.png         write the next drawn frame (what the window shows)
  camera [FILE.toml]          print (or write) the camera as a [camera] table
  reset                       reset the camera
  quit                        close the window""".format(n=len(METHODS), names=", ".join(METHODS))


@dataclass
class Command:
    name: str
    args: list
    text: str
    state: object = None  # progress of a command spread over frames


_ARITY = {  # name: (min args, max args, converters)
    "orbit": (2, 3, (float, float, int)),
    "pan": (2, 3, (float, float, int)),
    "zoom": (1, 2, (float, int)),
    "key": (1, 1, (str,)),
    "method": (1, 1, (str,)),
    "resize": (2, 2, (int, int)),
    "wait": (0, 0, ()),
    "frames": (1, 1, (int,)),
    "sleep": (1, 1, (float,)),
    "save": (1, 1, (str,)),
    "screenshot": (1, 1, (str,)),
    "camera": (0, 1, (str,)),
    "reset": (0, 0, ()),
    "quit": (0, 0, ()),
}
_KEY_NAMES = set(BINDINGS)


def parse_script(text: str, where: str = "--events") -> list[Command]:
    """Commands of SCRIPT_HELP; raises InputError naming the bad one."""
    out = []
    for raw_line in text.splitlines():
        line = raw_line.split("#", 1)[0]
        for part in line.split(";"):
            part = part.strip()
            if not part:
                continue
            words = shlex.split(part)
            name, args = words[0].lower(), words[1:]
            if name not in _ARITY:
                raise InputError(f"{where}: unknown command {name!r} in {part!r} (expected one of {', '.join(_ARITY)})")
            lo, hi, kinds = _ARITY[name]
            if not lo <= len(args) <= hi:
                raise InputError(f"{where}: {part!r}: {name} takes {lo}{'' if lo == hi else f' to {hi}'} arguments")
            try:
                values = [kind(a) for kind, a in zip(kinds, args)]
            except ValueError:
                raise InputError(f"{where}: {part!r}: bad number") from None
            if name in ("frames", "orbit", "pan", "zoom") and len(values) == hi and values[-1] < 1:
                raise InputError(f"{where}: {part!r}: the frame count must be at least 1")
            if name == "resize" and min(values) < 1:
                raise InputError(f"{where}: {part!r}: the size must be at least 1x1")
            if name == "key" and values[0].lower() not in _KEY_NAMES:
                raise InputError(f"{where}: {part!r}: unknown key (expected one of {', '.join(sorted(_KEY_NAMES))})")
            if name == "method" and values[0] not in METHODS:
                raise InputError(f"{where}: {part!r}: unknown method (expected one of {', '.join(METHODS)})")
            if name in ("save", "screenshot") and not values[0].lower().endswith(".png"):
                raise InputError(f"{where}: {part!r}: the file name must end in .png")
            out.append(Command(name, values, part))
    return out


def advance(app, commands) -> None:
    """Run the script (a deque of Command) as far as this frame allows."""
    while commands:
        if not _run(app, commands[0]):
            return
        commands.popleft()


def _run(app, cmd: Command) -> bool:
    """Do (part of) cmd on app (the :class:`bsrt.preview.app.Preview`); True when it is finished.
    One branch per command, hence the length."""
    name, a, state = cmd.name, cmd.args, cmd.state
    if name in ("orbit", "pan", "zoom"):
        frames = a[-1] if len(a) == (3 if name != "zoom" else 2) else 1
        if name == "orbit":
            app.move(orbit(app.camera, a[0] / frames, a[1] / frames))
        elif name == "pan":
            app.move(pan(app.camera, a[0] / frames, a[1] / frames, app.aspect()))
        else:
            app.move(zoom(app.camera, a[0] ** (1.0 / frames)))
        cmd.state = (state or 0) + 1
        return cmd.state >= frames
    if name == "key":
        app.press(a[0])
    elif name == "method":
        app.set_method(a[0])
    elif name == "resize":  # finished once the window has the size and the application its framebuffer
        if state is None:
            app.window.set_size(a[0], a[1])
            cmd.state = time.perf_counter() + RESIZE_SECONDS
            return False
        fb = app.window.framebuffer_size()
        done = app.window.size() == (a[0], a[1]) and app.fb_size == fb
        return done or time.perf_counter() > state  # a window manager may refuse the size
    elif name == "wait":
        return app.refine.complete or app.refine.failed is not None
    elif name == "frames":
        cmd.state = (state or 0) + 1
        return cmd.state > a[0]
    elif name == "sleep":
        if state is None:
            cmd.state = time.perf_counter() + a[0]
            return False
        return time.perf_counter() >= state
    elif name == "save":
        if app.refine.failed is not None:
            raise RenderError(f"{cmd.text}: {app.refine.failed}")
        if not app.refine.complete:
            return False
        app.request_save(Path(a[0]))
    elif name == "screenshot":  # finished once this frame is drawn (and written)
        if state is None:
            cmd.state = Path(a[0])
            app.pending_screenshots.append(cmd.state)
            return False
        return state not in app.pending_screenshots
    elif name == "camera":
        text = camera_toml(app.camera)
        if a:
            Path(a[0]).write_text(text, encoding="utf-8")
        else:
            print(text, flush=True)
    elif name == "reset":
        app.move(app.home)
    elif name == "quit":
        app.quit = True
    else:
        raise AssertionError(name)
    return True

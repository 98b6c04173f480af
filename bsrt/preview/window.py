"""The preview's glfw window: opening it with an OpenGL 3.3 core context,
turning glfw's input callbacks into named events for the application, and
the few window calls the frame loop needs. The only module that imports glfw.

Key codes become names through :data:`KEY_NAMES` (data, not code); the
application maps names to actions (``app.BINDINGS``).
"""

from __future__ import annotations

import os
import re
import sys

import glfw

from bsrt.errors import InputError, RenderError
from bsrt.rendering import gl

# glfw key -> the name the application binds (and the script's ``key NAME``).
# Keys in REPEATING also act on auto-repeat; the others once per press.
KEY_NAMES = {
    glfw.KEY_LEFT: "left",
    glfw.KEY_RIGHT: "right",
    glfw.KEY_UP: "up",
    glfw.KEY_DOWN: "down",
    glfw.KEY_KP_ADD: "plus",
    glfw.KEY_EQUAL: "plus",
    glfw.KEY_PAGE_UP: "plus",
    glfw.KEY_KP_SUBTRACT: "minus",
    glfw.KEY_MINUS: "minus",
    glfw.KEY_PAGE_DOWN: "minus",
    glfw.KEY_ESCAPE: "escape",
    glfw.KEY_M: "m",
    glfw.KEY_S: "s",
    glfw.KEY_C: "c",
    glfw.KEY_R: "r",
    glfw.KEY_Q: "q",
    glfw.KEY_1: "1",
    glfw.KEY_2: "2",
    glfw.KEY_3: "3",
    glfw.KEY_4: "4",
    glfw.KEY_KP_1: "1",
    glfw.KEY_KP_2: "2",
    glfw.KEY_KP_3: "3",
    glfw.KEY_KP_4: "4",
}
REPEATING = {"left", "right", "up", "down", "plus", "minus", "escape"}
SHIFTABLE = {"left", "right", "up", "down"}  # Shift+arrow is its own name: "shift+left"
MOUSE_BUTTONS = {glfw.MOUSE_BUTTON_LEFT: "orbit", glfw.MOUSE_BUTTON_RIGHT: "pan", glfw.MOUSE_BUTTON_MIDDLE: "pan"}


def _glfw_message(exc) -> str:
    """glfw's "(65550) b'X11: ...'" as "X11: ..."."""
    match = re.fullmatch(r"\((\d+)\) b?(['\"])(.*)\2", str(exc).strip(), re.S)
    return match.group(3) if match else str(exc)


class Window:
    """A glfw window with its moderngl context. handler gets the events:
    ``on_key(name)``, ``on_drag(button, down)`` (button "orbit" or "pan"),
    ``on_cursor(dx, dy, window_height)``, ``on_scroll(dy)``,
    ``on_framebuffer(width, height)``, ``on_refresh()``."""

    def __init__(self, handler, scene_path):
        self.handler, self.scene_path = handler, scene_path
        self.handle = None
        self.ctx = None
        self.cursor = (0.0, 0.0)

    def open(self, width: int, height: int, title: str):
        """Open the window and make its context current; returns the moderngl context."""
        glfw.ERROR_REPORTING = {
            getattr(glfw, "FEATURE_UNAVAILABLE", 0x1000C): "ignore",
            getattr(glfw, "FEATURE_UNIMPLEMENTED", 0x1000D): "ignore",
            None: "raise",
        }
        if sys.platform.startswith("linux") and os.environ.get("DISPLAY") and hasattr(glfw, "PLATFORM_X11"):
            glfw.init_hint(glfw.PLATFORM, glfw.PLATFORM_X11)  # GLX, what moderngl finds first
        try:
            ok = glfw.init()
        except glfw.GLFWError as exc:
            raise self._no_display(_glfw_message(exc)) from None
        if not ok:
            raise self._no_display("glfw.init() failed")
        try:
            glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
            glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
            glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
            glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
            glfw.window_hint(glfw.DEPTH_BITS, 24)
            glfw.window_hint(glfw.SCALE_TO_MONITOR, True)
            self.handle = glfw.create_window(width, height, title, None, None)
        except glfw.GLFWError as exc:
            glfw.terminate()
            raise RenderError(
                f"cannot open the preview window: {_glfw_message(exc)}; render without a window: "
                f"bsrt render {self.scene_path} -o out.png"
            ) from None
        if not self.handle:
            glfw.terminate()
            raise RenderError(
                f"cannot open the preview window; render without a window: bsrt render {self.scene_path} -o out.png"
            )
        glfw.make_context_current(self.handle)
        glfw.swap_interval(0)  # frames are paced by the application; a blocking swap would delay input
        try:
            self.ctx = gl.create_window_context()
        except RenderError:
            self.close()
            raise
        w = self.handle
        glfw.set_key_callback(w, self._on_key)
        glfw.set_mouse_button_callback(w, self._on_mouse_button)
        glfw.set_cursor_pos_callback(w, self._on_cursor)
        glfw.set_scroll_callback(w, self._on_scroll)
        glfw.set_framebuffer_size_callback(w, self._on_framebuffer_size)
        glfw.set_window_refresh_callback(w, lambda window: self.handler.on_refresh())
        self.cursor = glfw.get_cursor_pos(w)
        return self.ctx

    def _no_display(self, detail: str) -> InputError:
        return InputError(
            f"no display for the preview window ({detail.strip()}); set DISPLAY (or run it under xvfb-run), "
            f"or render without a window: bsrt render {self.scene_path} -o out.png"
        )

    # ---- what the frame loop calls

    def framebuffer_size(self) -> tuple[int, int]:
        return tuple(glfw.get_framebuffer_size(self.handle))

    def size(self) -> tuple[int, int]:
        """The window's size in screen coordinates."""
        return tuple(glfw.get_window_size(self.handle))

    def should_close(self) -> bool:
        return bool(glfw.window_should_close(self.handle))

    def swap(self) -> None:
        glfw.swap_buffers(self.handle)

    def wait(self, seconds: float) -> None:
        """Handle input, waiting up to seconds for some (0: do not wait)."""
        if seconds > 0:
            glfw.wait_events_timeout(seconds)
        else:
            glfw.poll_events()

    def wake(self) -> None:
        """End wait() now (callable from any thread: the solver's outcome watchers)."""
        if self.handle is not None:
            glfw.post_empty_event()

    def set_title(self, title: str) -> None:
        glfw.set_window_title(self.handle, title)

    def set_size(self, width: int, height: int) -> None:
        glfw.set_window_size(self.handle, width, height)

    def make_current(self) -> None:
        glfw.make_context_current(self.handle)

    def close(self) -> None:
        if self.handle is not None:
            glfw.destroy_window(self.handle)
            self.handle = None
        glfw.terminate()

    # ---- glfw callbacks -> named events

    def _on_key(self, window, key, scancode, action, mods) -> None:
        name = KEY_NAMES.get(key)
        if name is None or not (action == glfw.PRESS or (action == glfw.REPEAT and name in REPEATING)):
            return
        if name in SHIFTABLE and mods & glfw.MOD_SHIFT:
            name = "shift+" + name
        self.handler.on_key(name)

    def _on_mouse_button(self, window, button, action, mods) -> None:
        self.cursor = glfw.get_cursor_pos(window)
        if button in MOUSE_BUTTONS:
            self.handler.on_drag(MOUSE_BUTTONS[button], action == glfw.PRESS)

    def _on_cursor(self, window, x, y) -> None:
        dx, dy = x - self.cursor[0], y - self.cursor[1]
        self.cursor = (x, y)
        if dx or dy:
            self.handler.on_cursor(dx, dy, glfw.get_window_size(window)[1])

    def _on_scroll(self, window, xoffset, yoffset) -> None:
        if yoffset:
            self.handler.on_scroll(yoffset)

    def _on_framebuffer_size(self, window, width, height) -> None:
        self.handler.on_framebuffer(width, height)

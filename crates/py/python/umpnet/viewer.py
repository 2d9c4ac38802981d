"""``render_mode="human"``: frames shown in a window, or written to a file when
no window can open.

A window needs pygame (``pip install umpnet[human]``) and a display (``DISPLAY``
or ``WAYLAND_DISPLAY``; ``SDL_VIDEODRIVER`` set by hand counts too). Without
them, as on a server or in CI, each frame replaces one PNG, and the ``umpnet``
logger says where once (a notice about the machine, not a Python warning,
so gymnasium's env checker stays quiet): an image viewer that reloads shows
the episode as it runs.
``frame_path=`` picks that file and asks for it (no window, no notice).
"""

from __future__ import annotations

import logging
import os
import tempfile
from pathlib import Path

import numpy as np


def _no_window_reason() -> str | None:
    """Why no window can open here, or None when one can."""
    try:
        import pygame  # noqa: F401
    except ImportError:
        return "pygame is not installed (pip install umpnet[human])"
    if not any(os.environ.get(v) for v in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER")):
        return "no display (DISPLAY and WAYLAND_DISPLAY are unset)"
    return None


class Viewer:
    """Shows (H, W, 3) uint8 frames at ``fps``, in a window titled ``title`` or
    in the PNG at ``frame_path``."""

    def __init__(self, title: str, fps: float, frame_path: str | os.PathLike | None = None):
        self.title, self.fps = title, float(fps)
        self.frame_path = None if frame_path is None else Path(frame_path)
        self._screen = None
        self._clock = None
        self._closed = False  # the user closed the window: frames are dropped from then on

    @property
    def backend(self) -> str:
        """``window`` or ``file``: where ``show`` puts the frames (decided at the first frame)."""
        return "window" if self._screen is not None else "file"

    def show(self, frame: np.ndarray) -> None:
        frame = np.ascontiguousarray(frame, dtype=np.uint8)
        if frame.ndim != 3 or frame.shape[2] != 3:
            raise ValueError(f"a frame must be (H, W, 3) uint8, got shape {frame.shape}")
        if self._closed:
            return
        if self._screen is None and self.frame_path is None:
            reason = _no_window_reason()
            if reason is None:
                self._open_window(frame.shape[:2])
            else:
                self.frame_path = Path(tempfile.gettempdir()) / f"umpnet-human-{os.getpid()}.png"
                logging.getLogger("umpnet").warning(
                    "render_mode='human': no window can open, %s; each frame is written to %s instead "
                    "(render_mode='rgb_array' returns the frames)",
                    reason,
                    self.frame_path,
                )
        if self._screen is not None:
            self._show_in_window(frame)
        else:
            self._write(frame)

    def _open_window(self, size) -> None:
        import pygame

        pygame.init()
        pygame.display.init()
        self._screen = pygame.display.set_mode((size[1], size[0]))
        pygame.display.set_caption(self.title)
        self._clock = pygame.time.Clock()

    def _show_in_window(self, frame: np.ndarray) -> None:
        import pygame

        for event in pygame.event.get():
            if event.type == pygame.QUIT:
                self.close()
                self._closed = True
                return
        if self._screen.get_size() != (frame.shape[1], frame.shape[0]):
            self._screen = pygame.display.set_mode((frame.shape[1], frame.shape[0]))
        self._screen.blit(pygame.surfarray.make_surface(frame.swapaxes(0, 1)), (0, 0))
        pygame.display.flip()
        self._clock.tick(self.fps)

    def _write(self, frame: np.ndarray) -> None:
        from PIL import Image

        # Replaced whole, so a viewer never reads half a frame.
        self.frame_path.parent.mkdir(parents=True, exist_ok=True)
        partial = self.frame_path.with_name(self.frame_path.name + ".partial")
        Image.fromarray(frame).save(partial, format="PNG")
        os.replace(partial, self.frame_path)

    def close(self) -> None:
        if self._screen is not None:
            import pygame

            pygame.display.quit()
            self._screen = None


def tile(frames: np.ndarray) -> np.ndarray:
    """(N, H, W, 3) frames as one image, in a grid as square as it fits."""
    n, h, w, _ = frames.shape
    cols = int(np.ceil(np.sqrt(n)))
    rows = int(np.ceil(n / cols))
    grid = np.zeros((rows * h, cols * w, 3), np.uint8)
    for i, f in enumerate(frames):
        r, c = divmod(i, cols)
        grid[r * h : (r + 1) * h, c * w : (c + 1) * w] = f
    return grid

"""``RecordEpisode``: a gymnasium wrapper that writes each episode's frames
(``env.render()``, so ``render_mode="rgb_array"``) to a GIF (Pillow) or an
MP4 (imageio-ffmpeg, which bundles ffmpeg)::

    env = umpnet.gym.RecordEpisode(gym.make("umpnet/Goal-v0", render_mode="rgb_array"), "out/videos")

Files are ``FOLDER/episode_0000.gif`` (or ``.mp4``) in episode order, each
written to a temporary name and renamed when complete, so an interrupted run
leaves no half-written video.
"""

from __future__ import annotations

import os
from pathlib import Path

import gymnasium as gym
import numpy as np

FORMATS = ("gif", "mp4")


class RecordEpisode(gym.Wrapper):
    def __init__(self, env: gym.Env, folder, format: str = "gif", fps: float | None = None, scale: int = 1):
        super().__init__(env)
        if format not in FORMATS:
            raise ValueError(f"format {format!r}: expected one of {', '.join(FORMATS)}")
        if env.render_mode != "rgb_array":
            raise ValueError("RecordEpisode records env.render(): make the env with render_mode='rgb_array'")
        if not (isinstance(scale, int) and 1 <= scale <= 16):
            raise ValueError(f"scale {scale!r}: expected an integer from 1 to 16")
        if format == "mp4":
            try:
                import imageio_ffmpeg  # noqa: F401
            except ImportError as e:
                raise ImportError("format='mp4' needs imageio-ffmpeg: pip install imageio-ffmpeg") from e
        self.folder, self.format, self.scale = Path(folder), format, scale
        self.fps = float(fps if fps is not None else env.metadata.get("render_fps", 4))
        self.folder.mkdir(parents=True, exist_ok=True)
        self.episodes = 0
        self._frames: list[np.ndarray] = []

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._frames = [self._frame()]
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._frames.append(self._frame())
        if terminated or truncated:
            info = {**info, "video": str(self._write())}
        return obs, reward, terminated, truncated, info

    def close(self):
        # An episode cut short by close() is still worth watching.
        if len(self._frames) > 1:
            self._write()
        super().close()

    def _frame(self) -> np.ndarray:
        frame = np.asarray(self.env.render(), np.uint8)
        if self.scale > 1:
            frame = frame.repeat(self.scale, axis=0).repeat(self.scale, axis=1)
        return frame

    def _write(self) -> Path:
        path = self.folder / f"episode_{self.episodes:04d}.{self.format}"
        partial = path.with_name(f".{path.name}.partial.{os.getpid()}")
        try:
            if self.format == "gif":
                _gif(partial, self._frames, self.fps)
            else:
                _mp4(partial, self._frames, self.fps)
            partial.replace(path)
        finally:
            partial.unlink(missing_ok=True)
        self.episodes += 1
        self._frames = []
        return path


def _gif(path: Path, frames, fps: float):
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    duration = max(round(1000 / fps), 20)
    images[0].save(path, format="GIF", save_all=True, append_images=images[1:], duration=duration, loop=0)


def _mp4(path: Path, frames, fps: float):
    import imageio_ffmpeg

    h, w = frames[0].shape[:2]
    # yuv420p needs even sides: pad by a pixel where needed.
    ph, pw = h + h % 2, w + w % 2
    writer = imageio_ffmpeg.write_frames(
        str(path), (pw, ph), fps=fps, codec="libx264", pix_fmt_out="yuv420p", macro_block_size=1,
        output_params=["-f", "mp4"],
    )  # fmt: skip
    writer.send(None)
    for f in frames:
        if (ph, pw) != (h, w):
            f = np.pad(f, ((0, ph - h), (0, pw - w), (0, 0)), mode="edge")
        writer.send(np.ascontiguousarray(f))
    writer.close()

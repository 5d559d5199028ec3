"""What is drawn over a video frame, and the preview made from the frames (used by :mod:`cartpole.viz.video`).

* **The overlay** (:class:`Overlay`, Pillow on each frame): the time, each pole's angle from upright (the error from
  ``x_eq`` wrapped to (-180, 180] degrees, in the link's colour, :data:`~cartpole.viz.scene.LINK_COLOURS`), each
  actuator's ctrl as a bar against its range (red when at the limit), and the controller's mode when ``modes`` says
  (:func:`modes_from_switches`, :func:`swingup_modes`; :func:`mode_labels` reads them at the frame times). It draws
  in a top and a bottom band only, whose heights the camera keeps the system out of.
* **The preview** (:func:`preview_window`, :func:`write_gif`): an animated GIF beside the mp4 (same stem, ``.gif``),
  about 4 s at 15 fps, 480 px wide, from the window with the last mode switch near its end (else the most motion),
  made from the same frames.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from cartpole.viz.scene import LINK_COLOURS, VideoUnavailable

#: Colours of the mode tag (RGB 0..255) by the label's first word, lower case; others get grey.
MODE_COLOURS = {"energy": (214, 120, 20), "swing-up": (214, 120, 20), "swingup": (214, 120, 20),
                "catch": (30, 140, 60), "lqr": (30, 140, 60), "tvlqr": (120, 70, 180), "mpc": (30, 100, 190),
                "pid": (150, 90, 40)}

# ---------------------------------------------------------------------------------------------------------------
# modes

#: How :func:`modes_from_switches` names the switching controller's modes.
MODE_LABELS = {"swingup": "energy", "catch": "LQR catch"}


def modes_from_switches(switches, *, initial: str = "energy", labels: dict | None = None) -> list:
    """The ``modes`` argument of :func:`render_video` from a switching controller's log.

    Parameters
    ----------
    switches : iterable
        :class:`~cartpole.control.switching.Switch` objects or dicts with ``t`` (s) and ``mode`` (as
        ``SwingupResult.metrics["switches"]`` holds them), in time order.
    initial : str
        Label shown from t = 0 until the first switch.
    labels : dict, optional
        Display label of each logged mode name (default :data:`MODE_LABELS`: "swingup" -> "energy",
        "catch" -> "LQR catch"); names not in it are shown as they are.

    Returns
    -------
    list of (float, str)
        ``[(0.0, initial), (t_1, label_1), ...]``: each label holds from its time to the next.
    """
    names = MODE_LABELS if labels is None else labels
    out = [(0.0, str(initial))]
    for s in switches:
        t, mode = (s["t"], s["mode"]) if isinstance(s, dict) else (s.t, s.mode)
        out.append((float(t), str(names.get(mode, mode))))
    return out


def swingup_modes(result) -> list:
    """The ``modes`` of a :class:`~cartpole.apps.swingup.SwingupResult` (read by duck typing: ``method``, ``metrics``).

    ``energy``: "energy" then "LQR catch" at each switch the controller logged (and back); ``trajopt``: "TVLQR"
    along the plan, "LQR" from the handover; ``mpc``: "MPC"; any other method: its name.
    """
    method = str(getattr(result, "method", "") or "")
    switches = (getattr(result, "metrics", None) or {}).get("switches") or []
    if method == "energy":
        return modes_from_switches(switches, initial="energy")
    if method == "trajopt":
        return modes_from_switches(switches, initial="TVLQR", labels={"catch": "LQR", "swingup": "TVLQR"})
    if method == "mpc":
        return modes_from_switches(switches, initial="MPC", labels={"catch": "LQR"})
    return [(0.0, method or "controller")]


def mode_labels(modes, times) -> list | None:
    """The mode label shown at each of ``times`` (s): a list of str or None (no label at that time), or None when
    ``modes`` is None (no mode shown at all).

    ``modes`` is a sequence of ``(t_start, label)`` pairs (each label holds from its time to the next; before the
    first, None) or a callable ``t -> label or None``. Raises :class:`~cartpole.viz.scene.VideoUnavailable` for
    anything else.
    """
    if modes is None:
        return None
    if callable(modes):
        return [None if (lab := modes(float(t))) is None else str(lab) for t in times]
    try:
        pairs = sorted(((float(t0), str(lab)) for t0, lab in modes), key=lambda p: p[0])
    except (TypeError, ValueError):
        raise VideoUnavailable("modes must be a sequence of (t_start, label) pairs or a callable t -> label; "
                               f"got {modes!r}.") from None
    starts = np.array([p[0] for p in pairs])
    out = []
    for t in times:
        k = int(np.searchsorted(starts, t + 1e-9, side="right")) - 1
        out.append(pairs[k][1] if k >= 0 else None)
    return out


# ---------------------------------------------------------------------------------------------------------------
# overlay


def _font(size: int, mono: bool = False):
    try:
        import matplotlib

        name = "DejaVuSansMono.ttf" if mono else "DejaVuSans.ttf"
        return ImageFont.truetype(str(Path(matplotlib.get_data_path()) / "fonts" / "ttf" / name), size)
    except Exception:  # no matplotlib fonts: Pillow's own
        return ImageFont.load_default(size)


class Overlay:
    """Draws the overlay on an (h, w, 3) uint8 frame: a top band (time, each pole's angle from upright in its link's
    colour, the mode tag on the right) and a bottom band (one ctrl bar per actuator against its range).

    Parameters
    ----------
    width, height : int, pixels
        Frame size.
    n_poles : int
        Angles shown (one per hinge).
    ctrl_names : sequence of str
        One bar per actuator, labelled with its name.
    ctrl_range : (nu, 2) array
        ``[low, high]`` of each bar (MuJoCo ctrl units); an infinite bound is replaced by ``ctrl_scale``.
    ctrl_scale : float
        The bar's half-range for an unbounded actuator (ctrl units; e.g. the largest ``|ctrl|`` logged).
    show_mode : bool
        Leave room for the mode tag at the top right.

    ``top`` and ``bottom`` are the bands' heights in pixels: the camera keeps the system out of them. ``BAR``,
    ``SATURATED`` and ``INK`` are the RGB (0..255) of a ctrl bar's fill, of its fill at the ctrl limit and of the text.
    """

    BAR = (40, 70, 160)
    SATURATED = (200, 30, 30)
    INK = (15, 15, 15)

    def __init__(self, width: int, height: int, n_poles: int, ctrl_names, ctrl_range, ctrl_scale, show_mode: bool):
        self.w, self.h = width, height
        self.fs = max(9, int(round(height / 24)))
        self.font = _font(self.fs, mono=True)
        self.bold = _font(self.fs)
        self.pad = max(3, self.fs // 3)
        self.line = int(round(self.fs * 1.35))
        measure = ImageDraw.Draw(Image.new("RGB", (1, 1)))
        self.char = measure.textlength("0", font=self.font)
        self.theta = ["θ"] if n_poles == 1 else [f"θ{i + 1}" for i in range(n_poles)]
        self.colours = [tuple(int(255 * c) for c in LINK_COLOURS[i % len(LINK_COLOURS)]) for i in range(n_poles)]
        self.show_mode = show_mode
        self.mode_w = int(measure.textlength("LQR catch", font=self.bold)) + 3 * self.pad if show_mode else 0
        # top band: "t  3.47 s" then one "[] th1  +10.3°" item per pole, wrapped to the width left by the mode tag
        self.t_w = int(self.char * 10)
        self.item_w = int(self.fs + self.pad + self.char * (len(self.theta[-1]) + 8)) + 2 * self.pad
        room = max(1, int((width - self.mode_w - self.t_w - 2 * self.pad) // self.item_w))
        self.per_row = room
        rows = max(1, -(-n_poles // room))
        self.top = 2 * self.pad + self.line * rows
        # bottom band: one bar per actuator
        self.ctrl_names = list(ctrl_names)
        nu = len(self.ctrl_names)
        cr = np.asarray(ctrl_range, float).reshape(nu, 2)
        self.lo = np.where(np.isfinite(cr[:, 0]), cr[:, 0], -ctrl_scale)
        self.hi = np.where(np.isfinite(cr[:, 1]), cr[:, 1], ctrl_scale)
        self.name_w = int(max([measure.textlength(s, font=self.font) for s in self.ctrl_names] + [0])) + self.pad
        self.bar_w = int(width * 0.32)
        self.bottom = (2 * self.pad + self.line * nu) if nu else 0

    @staticmethod
    def _shade(frame, x0, y0, x1, y1):
        region = frame[y0:y1, x0:x1]
        region[:] = (region.astype(np.uint16) * 2 // 7 + 182).astype(np.uint8)  # ~70 % white

    def draw(self, frame: np.ndarray, t: float, angles_deg, ctrl, mode: str | None) -> np.ndarray:
        """The frame (h, w, 3) uint8 with the overlay: time ``t`` (s), ``angles_deg`` (n_poles,), ``ctrl`` (nu,)."""
        p, L, fs = self.pad, self.line, self.fs
        n = len(angles_deg)
        top_w = min(self.w, self.t_w + min(n, self.per_row) * self.item_w + 2 * p)
        self._shade(frame, 0, 0, top_w, self.top)
        nu = len(self.ctrl_names)
        y_bars = self.h - self.bottom
        bars_w = min(self.w, self.name_w + self.bar_w + int(self.char * 6) + 3 * p)
        if nu:
            self._shade(frame, 0, y_bars, bars_w, self.h)
        img = Image.fromarray(frame)
        dr = ImageDraw.Draw(img)
        dr.text((p, p), f"t {t:5.2f} s", font=self.font, fill=self.INK)
        for i, a in enumerate(angles_deg):
            row, col = divmod(i, self.per_row)
            x = p + self.t_w + col * self.item_w
            y = p + row * L
            dr.rectangle([x, y + 2, x + fs - 2, y + fs], fill=self.colours[i])
            dr.text((x + fs + p, y), f"{self.theta[i]} {a:+6.1f}°", font=self.font, fill=self.INK)
        for k, name in enumerate(self.ctrl_names):
            y = y_bars + p + L * k
            u = float(ctrl[k])
            lo, hi = float(self.lo[k]), float(self.hi[k])
            dr.text((p, y), name, font=self.font, fill=self.INK)
            x0 = p + self.name_w
            x1 = x0 + self.bar_w
            yb0, yb1 = y + 2, y + fs
            dr.rectangle([x0, yb0, x1, yb1], fill=(240, 240, 240), outline=(80, 80, 80))
            span = max(hi - lo, 1e-12)
            pos = lambda v: x0 + (min(max(v, lo), hi) - lo) / span * (x1 - x0)  # noqa: E731
            zero = pos(0.0 if lo <= 0.0 <= hi else lo)
            at_limit = u <= lo + 1e-9 * span or u >= hi - 1e-9 * span
            xa, xb = sorted((zero, pos(u)))
            dr.rectangle([xa, yb0 + 1, max(xb, xa + 1), yb1 - 1], fill=self.SATURATED if at_limit else self.BAR)
            dr.line([zero, yb0 - 2, zero, yb1 + 2], fill=self.INK, width=max(1, fs // 12))
            dr.text((x1 + p, y), f"{u:+.2f}", font=self.font, fill=self.INK)
        if self.show_mode and mode:
            colour = MODE_COLOURS.get(mode.split()[0].lower(), (90, 90, 90))
            tw = int(dr.textlength(mode, font=self.bold))
            x1 = self.w - p
            x0 = x1 - tw - 2 * p
            dr.rounded_rectangle([x0, p - 1, x1, p + fs + 3], radius=max(2, fs // 3), fill=colour)
            dr.text((x0 + p, p), mode, font=self.bold, fill=(255, 255, 255))
        return np.asarray(img)


# ---------------------------------------------------------------------------------------------------------------
# preview


def preview_window(times, rollout, idx, modes_at, seconds: float) -> tuple[int, int]:
    """Frame range ``[j0, j1)`` of the preview, ``seconds`` (s) long: ending 1.5 s after the last mode switch if there
    is one, else the earliest window with at least 95 % of the most joint motion (sum of |qvel| over the frames).

    ``times`` (n_frames,) s are the frame times, ``idx`` (n_frames,) the rollout samples they show
    (:func:`~cartpole.viz.scene.frame_indices`), ``modes_at`` the label at each frame (:func:`mode_labels`) or None.
    """
    n = len(times)
    fps = 1.0 / (times[1] - times[0]) if n > 1 else 30.0
    k = max(1, min(n, int(round(seconds * fps))))
    if modes_at is not None:
        changes = [j for j in range(1, n) if modes_at[j] != modes_at[j - 1]]
        if changes:
            j1 = min(n, changes[-1] + int(round(1.5 * fps)))
            j0 = max(0, j1 - k)
            return j0, min(n, j0 + k)
    speed = np.abs(np.asarray(rollout.qvel)[idx]).sum(1)
    if n <= k:
        return 0, n
    window = np.convolve(speed, np.ones(k), mode="valid")
    j0 = int(np.argmax(window >= 0.95 * window.max()))  # the earliest window with nearly the most motion
    return j0, j0 + k


def write_gif(frames, path: Path, fps: float) -> None:
    """Write ``frames`` (a list of ``PIL.Image``, RGB) to ``path`` as an animated GIF at ``fps`` frames per second:
    one palette for every frame (no flicker, small), looping, frame delays that average exactly ``1 / fps`` s.
    Nothing is written for an empty list."""
    if not frames:
        return
    sample = frames[:: max(1, len(frames) // 6)][:6]
    strip = Image.new("RGB", (sample[0].width, sample[0].height * len(sample)))
    for i, f in enumerate(sample):
        strip.paste(f, (0, i * f.height))
    palette = strip.quantize(colors=128, method=Image.Quantize.MEDIANCUT)
    pal = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    # GIF delays are in 10 ms units: alternate them so the average is exactly 1/fps
    ideal = 1000.0 / fps
    durations = [int(round((i + 1) * ideal / 10.0)) * 10 - int(round(i * ideal / 10.0)) * 10 for i in range(len(pal))]
    pal[0].save(path, format="GIF", save_all=True, append_images=pal[1:], duration=durations, loop=0,
                optimize=False, disposal=1)

"""What a real camera does to the rendered picture: exposure (fixed, or adapting to the frame's brightness),
white balance, vignette, motion blur, sensor noise and JPEG compression.

The renderer gives a clean, noise-free image; a webcam in an atrium does not. `CameraPost` applies one game's
`CameraEffects` to every frame, drawing the per-frame parts (noise, whether and how the frame is blurred) from
its own seeded generator, so the same seed gives the same frames. With the lab's effects it returns the frame
untouched.
"""
from __future__ import annotations

import cv2
import numpy as np

from ncbot.robot_sim.scene_conditions import CameraEffects


class CameraPost:
    """Apply `effects` to uint8 RGB frames, one call per frame."""

    def __init__(self, effects: CameraEffects) -> None:
        self.effects = effects
        self.rng = np.random.default_rng(effects.seed)
        self._vignette: np.ndarray | None = None
        self._noise_lut = (effects.noise * np.sqrt(np.arange(256, dtype=np.float32) / 128.0 + 0.1)).astype(np.float32)
        self._bank: np.ndarray | None = None
        self._auto_gain: float | None = None   # auto exposure's current gain (None: not metered yet)

    def _unit_noise(self, shape: tuple[int, ...]) -> np.ndarray:
        """Unit Gaussian noise of `shape`: a random window of a seeded noise bank twice the frame's size
        (drawing a fresh field per frame costs more than rendering a small frame)."""
        height, width = shape[:2]
        if self._bank is None or self._bank.shape[0] < 2 * height or self._bank.shape[1] < 2 * width:
            self._bank = self.rng.standard_normal((2 * height, 2 * width, shape[2]), dtype=np.float32)
        y, x = int(self.rng.integers(height)), int(self.rng.integers(width))
        return self._bank[y:y + height, x:x + width]

    def _vignette_map(self, height: int, width: int) -> np.ndarray:
        if self._vignette is None or self._vignette.shape != (height, width):
            ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
            r2 = ((xs - width / 2) / (width / 2)) ** 2 + ((ys - height / 2) / (height / 2)) ** 2
            fall = 255.0 * (1.0 - self.effects.vignette * np.clip(r2 / 2.0, 0.0, 1.0))
            self._vignette = np.repeat(np.round(fall).astype(np.uint8)[:, :, None], 3, axis=2)
        return self._vignette

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        fx = self.effects
        if fx.identity:
            return frame
        # exposure and white balance as one per-channel gain, then the vignette, on uint8 (cv2 saturates)
        gain = np.asarray(fx.white_balance_gain, np.float64) * fx.exposure * self._auto_exposure(frame)
        out = cv2.transform(frame, np.diag(gain))
        if fx.vignette > 0:
            out = cv2.multiply(out, self._vignette_map(*frame.shape[:2]), scale=1.0 / 255.0)
        if fx.blur_probability > 0 and self.rng.random() < fx.blur_probability:
            out = _motion_blur(out, float(self.rng.uniform(*fx.blur_px)), float(self.rng.uniform(0, np.pi)))
        if fx.noise > 0:
            # shot noise grows with the signal (std `noise` at mid grey), plus a read-noise floor
            noise = cv2.multiply(cv2.LUT(out, self._noise_lut), self._unit_noise(out.shape))
            out = cv2.add(out, noise, dtype=cv2.CV_8U)
        if fx.jpeg_quality is not None:
            ok, data = cv2.imencode(".jpg", out[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, fx.jpeg_quality])
            if ok:
                out = np.ascontiguousarray(cv2.imdecode(data, cv2.IMREAD_COLOR)[:, :, ::-1])
        return out


    def _auto_exposure(self, frame: np.ndarray) -> float:
        """The auto-exposure gain for this frame (1 when off).

        Like a phone or robot camera, it meters the frame (a centre-weighted mean grey of a thumbnail, after
        white balance) and moves its gain part of the way towards the gain that would put that mean at the
        target: a white sheet filling the view comes out darker, a dark sleeve or the bystander's arm entering
        the view brightens the next frames, and a drifting light is partly followed. The first frame is
        metered and met in full (the camera was running before the game started). `exposure` stays a fixed
        bias on top (exposure compensation)."""
        fx = self.effects
        if fx.auto_exposure_rate <= 0.0:
            return 1.0
        thumb = cv2.resize(frame, (32, 24), interpolation=cv2.INTER_AREA).astype(np.float32)
        grey = thumb @ (np.asarray(fx.white_balance_gain, np.float32) * np.array([0.299, 0.587, 0.114], np.float32))  # RGB
        mean = float((grey * _CENTRE_WEIGHTS).sum()) * fx.exposure
        wanted = float(np.clip(fx.exposure_target * 255.0 / max(mean, 1.0), *AUTO_GAIN_LIMITS))
        if self._auto_gain is None:
            self._auto_gain = wanted
        else:
            self._auto_gain = float(np.exp((1 - fx.auto_exposure_rate) * np.log(self._auto_gain)
                                           + fx.auto_exposure_rate * np.log(wanted)))
        return self._auto_gain


AUTO_GAIN_LIMITS = (0.35, 3.0)   # how far the auto exposure can turn the gain down or up


def _centre_weights() -> np.ndarray:
    """Metering weights of a 32x24 thumbnail: a broad Gaussian on the centre (sums to 1)."""
    ys, xs = np.mgrid[0:24, 0:32].astype(np.float32)
    w = np.exp(-(((xs - 15.5) / 12.0) ** 2 + ((ys - 11.5) / 9.0) ** 2))
    return (w / w.sum()).astype(np.float32)


_CENTRE_WEIGHTS = _centre_weights()


def _motion_blur(image: np.ndarray, length: float, angle: float) -> np.ndarray:
    """Blur along a line of `length` pixels at `angle` (the camera or head moving during the exposure)."""
    if length < 1.0:
        return image
    size = int(np.ceil(length)) | 1
    kernel = np.zeros((size, size), np.float32)
    c = size // 2
    dx, dy = np.cos(angle) * length / 2, np.sin(angle) * length / 2
    cv2.line(kernel, (int(round(c - dx)), int(round(c - dy))), (int(round(c + dx)), int(round(c + dy))), 1.0, 1, cv2.LINE_AA)
    kernel /= max(float(kernel.sum()), 1e-6)
    return cv2.filter2D(image, -1, kernel, borderType=cv2.BORDER_REFLECT)

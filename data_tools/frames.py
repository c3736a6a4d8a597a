"""Video frames: reading a video file or a folder of images, and where a frame is textured.

Used by the trackers (:mod:`data_tools.video`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["IMAGE_SUFFIXES", "TEXTURE_THRESHOLD", "load_frames", "read_frames", "texture_mask"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".ppm", ".pgm", ".webp")

#: Minimum eigenvalue of the structure tensor (``cv2.cornerMinEigenVal``, 7 x 7 block, grey
#: levels 0-255) above which a pixel counts as textured. Pixel noise of 2 grey levels on a
#: flat image stays below 1.1e-4; the synthetic textures have a median of 7e-4.
TEXTURE_THRESHOLD = 2e-4


def _gray(frame):
    import cv2

    frame = np.asarray(frame)
    if frame.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if frame.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        frame = cv2.cvtColor(frame, code)
    if frame.dtype != np.uint8:
        frame = np.clip(frame, 0, 255).astype(np.uint8)
    return frame


def _bgr(frame):
    import cv2

    frame = np.asarray(frame)
    if frame.ndim == 2:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    if frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR)
    return frame


def read_frames(path, max_frames=None):
    """Yield the frames (BGR uint8) of a video file or of a folder of images.

    Raises
    ------
    FileNotFoundError
        The path does not exist.
    ValueError
        OpenCV cannot open the file, an image of the folder cannot be decoded, or the
        images differ in size.
    """
    import cv2

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"video {path} not found")
    count = 0
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise ValueError(f"folder {path} holds no images ({', '.join(IMAGE_SUFFIXES)})")
        shape = None
        for p in files:
            if max_frames is not None and count >= max_frames:
                return
            img = cv2.imread(str(p), cv2.IMREAD_COLOR)
            if img is None:
                raise ValueError(f"cannot decode image {p}")
            if shape is not None and img.shape != shape:
                raise ValueError(
                    f"image {p} is {img.shape[1]}x{img.shape[0]} but the first "
                    f"image is {shape[1]}x{shape[0]}"
                )
            shape = img.shape
            count += 1
            yield img
        return
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise ValueError(f"cannot read {path}: OpenCV cannot open it as a video")
    try:
        while max_frames is None or count < max_frames:
            ok, frame = cap.read()
            if not ok:
                break
            count += 1
            yield _bgr(frame)
    finally:
        cap.release()


def load_frames(source, max_frames=None):
    """All frames of a video file, a folder of images, or an array, as (F, H, W, 3) uint8.

    Raises
    ------
    FileNotFoundError, ValueError
        Unreadable input (see :func:`read_frames`), fewer than 2 frames, frames of
        different sizes.
    """
    if isinstance(source, (str, Path)):
        frames = list(read_frames(source, max_frames))
        where = f"{source}"
    else:
        frames = [_bgr(f) for f in source]
        if max_frames is not None:
            frames = frames[:max_frames]
        where = "the input"
    if len(frames) == 0 and isinstance(source, (str, Path)) and Path(source).is_file():
        raise ValueError(f"cannot decode any frame from {where}: not a video OpenCV can read")
    if len(frames) < 2:
        raise ValueError(f"{where} has {len(frames)} frame(s); tracking needs at least 2")
    shapes = {f.shape for f in frames}
    if len(shapes) > 1:
        raise ValueError(f"frames of {where} differ in size: {sorted(shapes)}")
    return np.stack(frames)


def texture_mask(gray, block=7, threshold=TEXTURE_THRESHOLD):
    """(H, W) bool: pixels whose structure tensor's smaller eigenvalue exceeds ``threshold``."""
    import cv2

    return cv2.cornerMinEigenVal(_gray(gray), block) > threshold

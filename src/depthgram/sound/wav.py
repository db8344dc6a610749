"""Writing audio: 16-bit PCM WAV through soundfile."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from depthgram.errors import InputError

__all__ = ["write_wav"]


def write_wav(path: str | Path, audio: ArrayLike, samplerate: int) -> Path:
    """Write mono (n,) or stereo (n, 2) audio in -1..1 as a 16-bit PCM WAV file.

    Parameters
    ----------
    path : str or Path
        File to write; its folder must exist.
    audio : array_like, shape (n,) or (n, channels)
        Samples in -1..1; values beyond are clipped.
    samplerate : int
        Samples per second (Hz).

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    InputError
        When the audio is not 1-D or 2-D, holds NaN or infinity, or the folder is missing.
    """
    from depthgram._optional import needs_extra

    with needs_extra("sound", "writing WAV files"):
        import soundfile as sf

    p = Path(path)
    a = np.asarray(audio, dtype=np.float64)
    if a.ndim not in (1, 2) or (a.ndim == 2 and not 1 <= a.shape[1] <= 8):
        raise InputError(f"{p}: expected audio of shape (n,) or (n, channels), got {a.shape}")
    if not np.isfinite(a).all():
        raise InputError(f"{p}: audio holds NaN or infinite samples")
    if not isinstance(samplerate, (int, np.integer)) or samplerate <= 0:
        raise InputError(f"{p}: samplerate must be a positive integer (Hz), got {samplerate!r}")
    if not p.parent.is_dir():
        raise InputError(f"{p}: folder {p.parent} does not exist")
    from depthgram.atomic import atomic_path

    with atomic_path(p) as tmp:
        sf.write(str(tmp), np.clip(a, -1.0, 1.0), int(samplerate), subtype="PCM_16")
    return p

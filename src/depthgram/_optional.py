"""Optional dependencies: which extra installs each, and a clear error when one is missing.

``pip install depthgram`` brings what segmentation, the grammar, tracking, actions and the
command line need; bags, pictures, WAV files, the browser viewer and Dask clusters each need
an extra (``pip install 'depthgram[bags]'``, ...).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from depthgram.errors import MissingExtraError

__all__ = ["EXTRAS", "extra_for", "needs_extra"]

#: Top-level module of an optional dependency -> the extra of depthgram that installs it.
EXTRAS = {
    "rosbags": "bags",
    "matplotlib": "report",
    "soundfile": "sound",
    "sounddevice": "listen",
    "fastapi": "view",
    "starlette": "view",
    "uvicorn": "view",
    "websockets": "view",
    "dask": "dask",
    "distributed": "dask",
    "pyrealsense2": "realsense",
    "mcap": "mcap",
    "mcap_protobuf": "mcap",
    "foxglove_schemas_protobuf": "mcap",
    "foxglove": "foxglove",
}


def extra_for(exc: ModuleNotFoundError) -> MissingExtraError | None:
    """Return the :class:`MissingExtraError` for a missing optional module, None for any other module."""
    top = (exc.name or "").partition(".")[0]
    extra = EXTRAS.get(top)
    if extra is None:
        return None
    return MissingExtraError(f"this needs the optional package {top!r}: pip install 'depthgram[{extra}]'")


@contextmanager
def needs_extra(extra: str, what: str) -> Iterator[None]:
    """Turn a missing optional module imported inside the block into a :class:`MissingExtraError`.

    Parameters
    ----------
    extra : str
        The extra that installs it (``bags``, ``report``, ``sound``, ``view``, ``dask``).
    what : str
        What needs it, for the message (``"writing WAV files"``).
    """
    try:
        yield
    except ModuleNotFoundError as exc:
        raise MissingExtraError(
            f"{what} needs the optional package {exc.name!r}: pip install 'depthgram[{extra}]'"
        ) from exc

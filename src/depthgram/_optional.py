"""Optional dependencies: which extra installs each, and a clear error when one is missing.

``pip install depthgram`` brings what segmentation, the grammar, tracking, actions and the
command line need; bags, pictures, WAV files, the browser viewer and Dask clusters each need
an extra (``pip install 'depthgram[bags]'``, ...).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from depthgram.errors import MissingExtraError

__all__ = ["EXTRAS", "PIP_NAMES", "extra_for", "needs_extra", "package_of"]

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


#: Top-level module -> the name pip installs it by, where the two differ.
PIP_NAMES = {
    "mcap_protobuf": "mcap-protobuf-support",
    "foxglove_schemas_protobuf": "foxglove-schemas-protobuf",
    "foxglove": "foxglove-sdk",
}


def package_of(module: str | None) -> str:
    """Return the pip package that installs ``module`` (``matplotlib.backends`` -> ``matplotlib``).

    Users install packages, not sub-modules: a message naming ``matplotlib.backends`` or
    ``mcap.well_known`` sent them looking for something pip does not know (issue 32.6).
    """
    top = (module or "").partition(".")[0]
    return PIP_NAMES.get(top, top)


def extra_for(exc: ModuleNotFoundError) -> MissingExtraError | None:
    """Return the :class:`MissingExtraError` for a missing optional module, None for any other module."""
    top = (exc.name or "").partition(".")[0]
    extra = EXTRAS.get(top)
    if extra is None:
        return None
    return MissingExtraError(f"this needs the optional package {package_of(top)!r}: pip install 'depthgram[{extra}]'")


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
            f"{what} needs the optional package {package_of(exc.name)!r}: pip install 'depthgram[{extra}]'"
        ) from exc

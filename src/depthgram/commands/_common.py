"""Arguments shared by the sub-commands that read a source and run the pipeline."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from depthgram.pipeline import Config, Pipeline, SceneResult
    from depthgram.sources import Source


def add_pipeline_arguments(
    p: argparse.ArgumentParser, *, stills: bool = False, input_optional: bool = False, workers: bool = True
) -> None:
    """INPUT, how to read it (--stills among the reading options), the settings, --workers and --quiet.

    ``stills`` is kept for callers of the time when only some commands had --no-track; every
    command now has --stills (alias --no-track).

    ``input_optional`` only for commands whose output switch took a file in this release
    (``plan --json INPUT`` of the last release parses INPUT as the file: :func:`output_target`).
    ``workers`` false for a command that processes one frame at a time by design (``run``).
    """
    add_source_arguments(p, input_optional=input_optional)
    add_config_arguments(p)
    if workers:
        p.add_argument(
            "--workers",
            type=_positive_int,
            default=1,
            metavar="N",
            help="segment N frames at once in worker processes (same results, more frames/s on N cores; default 1)",
        )
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def pipeline_results(args: argparse.Namespace, desc: str) -> tuple[Source, Iterator[SceneResult]]:
    """Open the input, run the configured pipeline over it, with a progress bar."""
    src = open_input(args)
    pipe = make_pipeline(args)
    results = pipe.run(src, workers=getattr(args, "workers", 1))
    return src, progress(results, total=source_len(src), desc=desc, quiet=args.quiet)


def make_pipeline(args: argparse.Namespace) -> Pipeline:
    """Return the pipeline the arguments configure (--config, --method, --stills, --trust-intrinsics)."""
    from depthgram.pipeline import Pipeline

    return Pipeline(load_config(args), check_intrinsics=not getattr(args, "trust_intrinsics", False))


def _positive_int(text: str) -> int:
    """Parse a count of at least 1 (argparse type)."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, got {n}")
    return n


#: Segmentation methods offered by --method (a test checks them against depthgram.segmentation.METHODS;
#: importing the package here would load the compiled kernels before the command is even chosen).
METHODS = ("surfaces", "slices", "threshold", "region", "paper")

#: Depth encodings offered by --encoding (checked against depthgram.sources.ENCODINGS by a test).
ENCODINGS = ("auto", "raw", "mm", "m", "8bit", "sun", "kinect-disparity")


def add_source_arguments(p: argparse.ArgumentParser, *, input_optional: bool = False) -> None:
    """INPUT and the options that say how to read it."""
    p.add_argument(
        "input",
        metavar="INPUT",
        nargs="?" if input_optional else None,
        help="file, folder or glob of depth frames, .npy/.npz stack, ROS bag / MCAP, realsense:[SERIAL], "
        "or sim:SCENE (table, corridor, approach, crossing, ball_wall, touching, arm_down, arm_45, chest_walk, "
        "ball_approach, ball_rush, pass_behind, cross_front; "
        "?sensor=sl: structured light)",
    )
    add_reading_arguments(p)


def add_reading_arguments(p: argparse.ArgumentParser) -> None:
    """Return the options that say how to read a recording, the same for every command that reads one.

    :func:`reading_options` turns them into the keyword arguments of
    :func:`depthgram.sources.open_source` (``depthgram batch`` passes them to every recording).
    """
    g = p.add_argument_group("reading the input")
    g.add_argument(
        "--scale",
        type=float,
        default=None,
        metavar="MM_PER_UNIT",
        help="millimetres per raw unit (default 1 for integer images, 1000 for float = metres; "
        "0.2 for TUM's 5000 per metre, 0.1 for YCB-Video)",
    )
    g.add_argument(
        "--invalid",
        type=float,
        nargs="+",
        default=[],
        metavar="VALUE",
        help="raw values that mean no reading (0 always does, and 65535 in 16-bit images)",
    )
    g.add_argument(
        "--fps", type=float, default=None, metavar="RATE", help="frame rate (frames/s) of frames without timestamps"
    )
    g.add_argument(
        "--timestamps", default=None, metavar="FILE", help="file with one time (s) per frame, or 'index time' pairs"
    )
    g.add_argument(
        "--encoding",
        default="auto",
        choices=ENCODINGS,
        help="sample encoding: auto; mm / m (units whatever the dtype); 8bit (the paper's 0-255, "
        "with --range); sun (SUN RGB-D bit shift); kinect-disparity (NYU raw PGM)",
    )
    g.add_argument(
        "--stills",
        "--no-track",
        dest="stills",
        default=None,
        nargs="?",
        const="yes",
        choices=["yes", "no", "auto"],
        help="the frames are unrelated still images: no motion (velocity, time to collision, approach "
        "alarm) is read between them. 'no': one recording, always track; default 'auto' (or the "
        "config's 'stills'): tracks are dropped between frames with nothing in common",
    )
    g.add_argument(
        "--range",
        type=float,
        nargs=2,
        default=None,
        metavar=("NEAR_MM", "FAR_MM"),
        dest="depth_range",
        help="depth range in mm: of the 8-bit codes 1..255, else the valid range",
    )
    g.add_argument("--topic", default=None, help="depth Image topic of a ROS bag (when it has several)")
    g.add_argument("--key", default=None, help="array name inside an .npz")
    g.add_argument(
        "--intrinsics",
        type=float,
        nargs=4,
        default=None,
        metavar=("FX", "FY", "CX", "CY"),
        help="camera intrinsics in pixels, for the frames as read (override sidecars, a bag's CameraInfo)",
    )
    g.add_argument(
        "--camera",
        default=None,
        metavar="FILE_OR_PROFILE",
        help="calibration file (ROS camera_info or OpenCV/Kalibr YAML, Open3D JSON, 3x3 matrix text) or a "
        "camera profile (kinect-v1, xtion, realsense-d435, azure-kinect-nfov, ...: intrinsics and sensor model)",
    )
    g.add_argument(
        "--trust-intrinsics",
        action="store_true",
        help="use --intrinsics/--camera as they are, even where the scene's right angles say another focal length",
    )
    g.add_argument(
        "--gravity",
        type=float,
        nargs=3,
        default=None,
        metavar=("X", "Y", "Z"),
        help="which way is down in camera coordinates (x right, y down, z forward; any length); overrides a bag's IMU",
    )
    g.add_argument(
        "--tilt", type=float, default=None, metavar="DEG", help="the camera looks down DEG degrees (no roll)"
    )


def reading_options(args: argparse.Namespace) -> dict[str, Any]:
    """Return the reading options of ``args`` as keyword arguments of :func:`depthgram.sources.open_source`."""
    kwargs: dict[str, Any] = {
        "scale_mm": args.scale,
        "invalid": tuple(args.invalid),
        "fps": args.fps,
        "timestamps": args.timestamps,
        "encoding": args.encoding,
        "topic": args.topic,
        "key": args.key,
        "intrinsics": tuple(args.intrinsics) if args.intrinsics is not None else None,
        "camera": args.camera,
        "gravity": tuple(args.gravity) if args.gravity is not None else None,
        "tilt_deg": args.tilt,
    }
    if args.depth_range is not None:
        kwargs["depth_range_mm"] = tuple(args.depth_range)
    return kwargs


def add_config_arguments(p: argparse.ArgumentParser) -> None:
    """--config and the most used segmentation setting."""
    p.add_argument("--config", default=None, metavar="TOML", help="pipeline settings (see depthgram config --dump)")
    p.add_argument(
        "--method", default=None, choices=METHODS, help="segmentation method (default from the config: surfaces)"
    )
    p.add_argument(
        "--raised",
        type=float,
        default=None,
        metavar="SIGMAS",
        help="cut what stands above any table or floor by more than SIGMAS of the sensor's noise into objects "
        "(flat things lying on a table seen at an angle; [segment] raised_sigmas = SIGMAS, raised_supports = "
        "'all'; by default a table seen from straight above and a table or floor filling a third of the view "
        "are cut, at 4; 0: none)",
    )


def open_input(args: argparse.Namespace) -> Source:
    """Open the source named by the arguments."""
    from depthgram.errors import InputError
    from depthgram.sources import open_source

    if args.input is None:
        raise InputError(f"INPUT is required: depthgram {args.command} INPUT ...")
    return open_source(args.input, **reading_options(args))


def load_config(args: argparse.Namespace) -> Config:
    """Return the pipeline configuration from --config and --method."""
    from depthgram.pipeline import Config

    cfg = Config.load(args.config) if getattr(args, "config", None) else Config()
    if getattr(args, "method", None):
        cfg = cfg.replace(segment={"method": args.method})
    if getattr(args, "raised", None) is not None:
        if not 0.0 <= args.raised <= 1000.0:
            from depthgram.errors import InputError

            raise InputError(f"--raised {args.raised:g}: expected sigmas of the sensor's noise in [0, 1000] (0: off)")
        cfg = cfg.replace(segment={"raised_sigmas": args.raised, "raised_supports": "all"})
    stills = getattr(args, "stills", None)
    if stills is not None:
        cfg = cfg.with_stills({"yes": True, "no": False}.get(stills, "auto"))
    return cfg


def progress(iterable: Any, *, total: int | None, desc: str, quiet: bool = False) -> Any:
    """Return a tqdm progress bar on standard error; silent with --quiet or when not a terminal."""
    from tqdm import tqdm

    return tqdm(
        iterable, total=total, desc=desc, unit="frame", disable=quiet or not sys.stderr.isatty(), file=sys.stderr
    )


def source_len(src: object) -> int | None:
    """Frame count when the source knows it."""
    try:
        return len(src)  # type: ignore[arg-type]
    except TypeError:
        return None


#: ``--json FILE``, ``--text FILE`` ...: '-' is standard output (the rosbags / ffmpeg convention).
STDOUT = "-"

#: What argparse stores for an output flag given without its file (the spelling of the last release).
_BARE = "\0bare"


def add_output_argument(p: argparse.ArgumentParser, flag: str, what: str, *, bare_deprecated: bool = False) -> None:
    """Return an output option that takes a file, ``-`` meaning standard output (the one convention).

    Parameters
    ----------
    p : ArgumentParser
        The command's parser.
    flag : str
        ``"--json"``, ``"--text"`` ...
    what : str
        What is written, for the help.
    bare_deprecated : bool
        The flag was a switch in the last release (``plan --json``, ``info --json``): given
        without a file it still writes to standard output, with a deprecation message
        (:func:`output_target`).
    """
    text = f"write {what} to FILE ('-': standard output)"
    if bare_deprecated:
        p.add_argument(flag, nargs="?", const=_BARE, default=None, metavar="FILE", help=text)
    else:
        p.add_argument(flag, default=None, metavar="FILE", help=text)


def deprecated(command: str, old: str, new: str) -> None:
    """Tell the user (on standard error) that a spelling goes in the next release."""
    print(
        f"depthgram {command}: warning: {old} is deprecated and will be removed in the next release; use {new}",
        file=sys.stderr,
    )


def output_target(args: argparse.Namespace, dest: str) -> str | None:
    """Return the file named by an output option: a path, :data:`STDOUT`, or None when not given.

    A bare deprecated switch (``plan --json``) gives :data:`STDOUT` and a deprecation message. The
    old spelling with the switch before the input (``plan --json INPUT``) had the input taken as
    the file: when INPUT is then missing, the value is moved back to it.
    """
    value = getattr(args, dest)
    flag = "--" + dest.replace("_", "-")
    if value == _BARE or (value is not None and getattr(args, "input", "") is None):
        if value != _BARE:
            args.input = value
        deprecated(args.command, f"{flag} without a file", f"{flag} - (standard output)")
        value = STDOUT
        setattr(args, dest, value)
    return value  # type: ignore[no-any-return]


class Output:
    """A text output named by an option: standard output for ``-``, else a file opened for writing.

    A context manager; the file is closed (standard output only flushed) on exit.
    """

    def __init__(self, target: str, option: str) -> None:
        from depthgram.errors import InputError

        self.target = target
        if target == STDOUT:
            self.stream: Any = sys.stdout
        else:
            from depthgram.atomic import atomic_open

            # under a temporary name until __exit__ without an error: a failure leaves no file
            # that looks complete (issue 18.7)
            self._atomic = atomic_open(target)
            try:
                self.stream = self._atomic.__enter__()
            except OSError as exc:
                raise InputError(f"{option} {target}: cannot write ({exc.strerror or exc})") from None

    def write(self, text: str) -> None:
        """Write ``text`` as it is."""
        self.stream.write(text)

    def __enter__(self) -> Output:
        return self

    def __exit__(self, *exc: Any) -> None:
        if self.stream is sys.stdout:
            self.stream.flush()
        else:
            self._atomic.__exit__(*exc)

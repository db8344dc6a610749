"""depthgram demo: the whole pipeline on bundled simulated scenes, written to a folder."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "demo"
HELP = "run the pipeline on the bundled simulated scenes (table, approach): JSON, report, plan, sound"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    p.add_argument("--out", default="demo-out", metavar="DIR", help="folder to write into (default demo-out)")
    p.add_argument("--frames", type=int, default=30, help="frames of the moving scene (default 30)")


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    import json

    from depthgram._optional import needs_extra
    from depthgram.act import plan_to_text
    from depthgram.errors import InputError
    from depthgram.pipeline import Pipeline
    from depthgram.sound import Sonifier
    from depthgram.sources import open_source

    with needs_extra("sound,report", "depthgram demo (sound and pictures)"):
        import matplotlib  # noqa: F401  (the report's pictures; checked here, before any work)
        import soundfile as sf

        from depthgram.views.report import ReportWriter

    if not 2 <= args.frames <= 10000:
        raise InputError(f"--frames must be between 2 and 10000, got {args.frames}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for scene, frames in (("table", 1), ("approach", args.frames)):
        src = open_source(f"sim:{scene}?frames={frames}")
        pipe = Pipeline()
        report = ReportWriter(
            out / scene / "report", every=max(1, frames // 4), max_pictures=4, source=f"sim:{scene}?frames={frames}"
        )
        fps = src.fps or 30.0
        sonifier: Sonifier | None = None
        last = None
        with (
            open(out / scene / "scenes.jsonl", "w", encoding="utf-8") as fh,
            sf.SoundFile(out / scene / "sound.wav", "w", samplerate=22050, channels=2, subtype="PCM_16") as wav,
        ):
            for result in pipe.run(src):
                fh.write(json.dumps(result.to_record()) + "\n")
                report.add(result)
                sonifier = sonifier or Sonifier(Pipeline().config.sound, 22050, result.frame.size)
                wav.write(sonifier.push(result.tree, 1.0 if frames == 1 else 1.0 / fps))
                last = result
        page = report.finish()
        if last is None:
            raise InputError(f"sim:{scene}: the simulator gave no frame")
        (out / scene / "plan.txt").write_text(plan_to_text(last.plan) + "\n", encoding="utf-8")
        print(f"{scene}: {frames} frame(s) -> {out / scene}/ (scenes.jsonl, sound.wav, plan.txt), report {page}")
        print(f"  last sentence: {last.sentence}")
    return 0

"""Replay the examples of issue 24 ("hostile input, signals and the cache") against the installed ``cartpole``
script and print, for each, its exit status, seconds, stderr lines and files left under --out.

Usage: ``python tools/hostile_repro.py [SUBSTRING ...]`` (only the cases whose name contains one). Every case should
end in exit status 2 and one sentence, with no file left. Fixtures (a symbolic-link loop, a FIFO, MJCF variants, a
results file on /dev/zero) are made in a temporary directory; the cache is ``$CARTPOLE_CACHE_DIR`` as set.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = ROOT / "cartpole" / "assets" / "cartpole.xml"


def _fixtures(tmp: Path) -> dict:
    os.symlink(tmp / "loop2", tmp / "loop1")
    os.symlink(tmp / "loop1", tmp / "loop2")
    os.mkfifo(tmp / "fifo")
    (tmp / "adir").mkdir()
    text = SHIPPED.read_text()
    variants = {"neggear": ('gear="20"', 'gear="-20"'), "bigctrl": ('ctrlrange="-1 1"', 'ctrlrange="-1e300 1e300"'),
                "hingerange": ('<joint name="hinge" type="hinge"',
                               '<joint name="hinge" type="hinge" limited="true" range="60 300"'),
                "tinystep": ('timestep="0.005"', 'timestep="1e-6"'),
                "incfifo": ("<worldbody>", f'<include file="{tmp / "fifo"}"/><worldbody>')}
    for name, (old, new) in variants.items():
        (tmp / f"{name}.xml").write_text(text.replace(old, new, 1))
    (tmp / "exitmod.py").write_text("raise SystemExit(7)\n")
    (tmp / "raisemod.py").write_text("raise RuntimeError('boom at import')\n")
    resume = tmp / "resume" / "sweeps"
    resume.mkdir(parents=True)
    os.symlink("/dev/zero", resume / "sweep_energy.csv")
    return {"tmp": str(tmp)}


def cases(t: str, out: str) -> list:
    """(name, argv, extra environment) of every example."""
    sw = ["swingup", "--no-video"]
    return [
        ("mjcf-symlink-loop", ["linearize", "--mjcf", f"{t}/loop1"], {}),
        ("mjcf-fifo", ["linearize", "--mjcf", f"{t}/fifo"], {}),
        ("mjcf-devzero", ["linearize", "--mjcf", "/dev/zero"], {}),
        ("mjcf-dir", ["linearize", "--mjcf", f"{t}/adir"], {}),
        ("mjcf-include-fifo", ["linearize", "--mjcf", f"{t}/incfifo.xml"], {}),
        ("out-empty", [*sw, "--duration", "1", "--out", ""], {}),
        ("sweep-seed-neg", ["sweep", "--seed", "-1", "--n", "1", "--duration", "1", "--out", out], {}),
        ("push-1e308", [*sw, "--push", "1e308:1", "--out", out], {}),
        ("sweep-pushtime-1e308", ["sweep", "--push-time", "1e308", "--push-force", "1", "--duration", "1", "--out",
                                  out], {}),
        ("push-after-end", [*sw, "--duration", "1", "--push", "5:1", "--out", out], {}),
        ("push-1e12", [*sw, "--push", "1:1e12", "--out", out], {}),
        ("sweep-push-force-1e12", ["sweep", "--push-force", "1e12", "--duration", "1", "--out", out], {}),
        ("x0-1e308-rate", [*sw, "--x0", "0", "3", "0", "1e308", "--out", out], {}),
        ("x0-1e308-angle", [*sw, "--x0", "0", "1e308", "0", "0", "--out", out], {}),
        ("mplbackend-bogus", [*sw, "--duration", "0.5", "--out", out], {"MPLBACKEND": "bogus"}),
        ("dask-garbage", ["sweep", "--n", "1", "--duration", "1", "--address", "garbage", "--out", out], {}),
        ("dask-http", ["sweep", "--n", "1", "--duration", "1", "--address", "http://127.0.0.1:9", "--out", out], {}),
        ("dask-closed-port", ["sweep", "--n", "1", "--duration", "1", "--address", "tcp://127.0.0.1:9", "--out",
                              out], {}),
        ("Q-huge", ["lqr", "--no-video", "--Q", "1e308", "1e308", "1e308", "1e308", "--out", out], {}),
        ("R-tiny", ["lqr", "--no-video", "--R", "1e-308", "--out", out], {}),
        ("mpc-horizon-1e6", [*sw, "--method", "mpc", "--horizon", "1e6", "--out", out], {}),
        ("mpc-period-horizon30", [*sw, "--method", "mpc", "--period", "0.005", "--horizon", "30", "--out", out], {}),
        ("mpc-horizon-below-period", [*sw, "--method", "mpc", "--period", "0.5", "--horizon", "0.2", "--out", out],
         {}),
        ("mpc-period-1e-9", [*sw, "--method", "mpc", "--period", "1e-9", "--out", out], {}),
        ("period-1e-9", [*sw, "--period", "1e-9", "--duration", "1", "--out", out], {}),
        ("lqr-dt-1e-6", ["lqr", "--mjcf", f"{t}/tinystep.xml", "--out", out], {}),
        ("objective-exit", ["swingup", "--method", "trajopt", "--objective", "exitmod:f", "--out", out],
         {"PYTHONPATH": t}),
        ("objective-raise", ["swingup", "--method", "trajopt", "--objective", "raisemod:f", "--out", out],
         {"PYTHONPATH": t}),
        ("objective-cwd", ["swingup", "--method", "trajopt", "--objective", "exitmod:f", "--out", out], {}),
        ("sweep-start-5", ["sweep", "--start", "slider", "5", "--duration", "1", "--out", out], {}),
        ("hinge-range", [*sw, "--mjcf", f"{t}/hingerange.xml", "--out", out], {}),
        ("ctrlrange-1e300", [*sw, "--mjcf", f"{t}/bigctrl.xml", "--out", out], {}),
        ("negative-gear", [*sw, "--mjcf", f"{t}/neggear.xml", "--out", out], {}),
        ("resume-devzero", ["sweep", "--n", "1", "--duration", "1", "--resume", "--out", f"{t}/resume"], {}),
        ("delay-1e6", ["lqr", "--no-video", "--delay", "1e6", "--out", out], {}),
        ("period-1e308", ["linearize", "--period", "1e308"], {}),
    ]


def main(select) -> int:
    """Run the selected cases; print one block each."""
    with tempfile.TemporaryDirectory(prefix="cartpole-hostile-") as tmp:
        fx = _fixtures(Path(tmp))
        out = str(Path(tmp) / "out")
        exe = shutil.which("cartpole") or str(Path(sys.executable).parent / "cartpole")
        for name, argv, extra in cases(fx["tmp"], out):
            if select and not any(s in name for s in select):
                continue
            shutil.rmtree(out, ignore_errors=True)
            t0 = time.monotonic()
            try:
                proc = subprocess.run([exe, *argv], env={**os.environ, **extra}, capture_output=True, text=True,
                                      timeout=120, cwd=tmp, check=False)
                rc, err = proc.returncode, proc.stderr
            except subprocess.TimeoutExpired:
                rc, err = "TIMEOUT", ""
            left = sorted(str(p.relative_to(out)) for p in Path(out).rglob("*") if p.is_file()) \
                if os.path.isdir(out) else []
            print(f"=== {name}: exit {rc}, {time.monotonic() - t0:.1f} s, {len(err.splitlines())} stderr line(s), "
                  f"files left {left}")
            for line in err.strip().splitlines()[-2:]:
                print("    " + line[:300])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

"""Fill ``gpu-deps/`` with the wheels a GPU machine without a package registry lacks
(``make gpu-deps``; docs/performance.md, "GPU (H100)"; issue 44).

The GPU machine brings its own CUDA PyTorch and the scientific base a PyTorch image has (numpy,
scipy, pillow, scikit-image, h5py, matplotlib: :data:`MACHINE_OWN`); everything else lfsam,
its SAM 2, EdgeTAM and SAM 3 back ends and the CUDA tests need is carried in as wheels, at
the exact versions installed in this checkout's ``.venv`` (which ``constraints.txt`` pins):
the roots in :data:`ROOTS` and their requirements, followed through the installed packages'
metadata. Meta's ``sam2`` is built here as a wheel without its optional CUDA extension (as
``make install`` installs it); a package published only as a source archive
(``antlr4-python3-runtime``) is built into a wheel; a compiled package is fetched for every
Python of ``--pythons`` (the machine's Python is not known here). ``gpu-deps/constraints.txt``
pins every wheel carried, and ``make gpu-check`` installs with ``pip install --no-index
--find-links gpu-deps -c gpu-deps/constraints.txt``. Never torch, torchvision, triton or
``nvidia-*``. The folder must stay under ``--max-mib`` (60).

Usage::

    python tools/gpu_deps.py --out gpu-deps [--pythons 3.11,3.12,3.13] [--max-mib 60]
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from importlib import metadata
from pathlib import Path

#: What ``make gpu-check`` installs besides lfsam itself (its core, the ``edgetam`` and
#: ``text`` extras' libraries, and the test tools the CUDA tests need).
ROOTS = ["lfsam", "transformers", "timm", "pytest", "hypothesis", "pytest-timeout",
         "setuptools", "wheel"]
#: Never carried: the machine's own CUDA PyTorch and the scientific base of a PyTorch image.
MACHINE_OWN = re.compile(
    r"^(torch|torchvision|torchaudio|triton|nvidia-.*|numpy|scipy|pillow|scikit-image|h5py|"
    r"matplotlib|contourpy|cycler|fonttools|kiwisolver|pyparsing|python-dateutil|six|"
    r"networkx|sympy|mpmath|jinja2|markupsafe|tifffile|lazy-loader|imageio)$")
#: Platforms a manylinux x86_64 wheel may be tagged with.
PLATFORMS = ["manylinux2014_x86_64", "manylinux_2_17_x86_64", "manylinux_2_28_x86_64",
             "manylinux_2_34_x86_64", "linux_x86_64"]


def canonical(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def closure(roots: list[str]) -> dict[str, str]:
    """Installed name -> version for the roots and everything they require (no extras, markers
    evaluated here), stopping at :data:`MACHINE_OWN`; lfsam itself is left out."""
    seen: dict[str, str] = {}
    todo = list(roots)
    while todo:
        name = canonical(todo.pop())
        if name in seen or MACHINE_OWN.match(name):
            continue
        try:
            dist = metadata.distribution(name)
        except metadata.PackageNotFoundError:
            raise SystemExit(f"gpu-deps: {name} is not installed in this environment; run "
                             "make install first") from None
        seen[name] = dist.version
        for req in dist.requires or []:
            head, _, marker = req.partition(";")
            if "extra" in marker:
                continue
            if marker.strip() and not _marker_holds(marker):
                continue
            todo.append(re.split(r"[\s\[<>=!~(;]", head.strip(), maxsplit=1)[0])
    seen.pop("lfsam", None)
    return seen


def _marker_holds(marker: str) -> bool:
    from packaging.markers import Marker

    return Marker(marker.strip()).evaluate()


def pip(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pip", *args], capture_output=True, text=True,
                          env=env)


def fetch(name: str, version: str, out: Path, pythons: list[str]) -> list[str]:
    """The package's wheels for every Python of ``pythons`` (a pure or abi3 wheel is one
    file), or a pure wheel built here from its source archive when it has none; returns the
    Pythons it has no wheel for (a package may require a newer Python)."""
    spec = f"{name}=={version}"
    missing = []
    for python in pythons:
        run = pip("download", "--quiet", "--no-deps", "--only-binary=:all:", "--dest", str(out),
                  "--python-version", python, "--implementation", "cp",
                  *[f"--platform={p}" for p in PLATFORMS], spec)
        if run.returncode != 0:
            missing.append(python)
    if len(missing) < len(pythons):
        return missing
    built = pip("wheel", "--quiet", "--no-deps", "--wheel-dir", str(out), spec)
    if built.returncode != 0:
        raise SystemExit(f"gpu-deps: no wheel of {spec}, and building one failed:\n"
                         f"{run.stderr[-800:]}\n{built.stderr[-800:]}")
    wheel = next(out.glob(f"{canonical(name).replace('-', '_')}-{version}-*.whl"), None)
    if wheel is None or not wheel.name.endswith("-none-any.whl"):
        raise SystemExit(f"gpu-deps: {spec} has no wheel and builds only a compiled one here "
                         f"({wheel and wheel.name})")
    return []


def build_sam2(version: str, out: Path) -> None:
    """Meta's sam2 as a wheel without its CUDA extension (torch is imported by its build)."""
    env = {**os.environ, "SAM2_BUILD_CUDA": "0", "SAM2_BUILD_ALLOW_ERRORS": "1"}
    run = pip("wheel", "--quiet", "--no-deps", "--no-build-isolation", "--wheel-dir", str(out),
              f"sam2=={version}", env=env)
    if run.returncode != 0:
        raise SystemExit(f"gpu-deps: building the sam2 wheel failed:\n{run.stderr[-1500:]}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="gpu-deps", type=Path)
    parser.add_argument("--pythons", default="3.11,3.12,3.13",
                        help="Pythons the GPU machine may run (compiled wheels for each)")
    parser.add_argument("--max-mib", type=float, default=60.0)
    args = parser.parse_args(argv)
    pythons = args.pythons.split(",")
    packages = closure(ROOTS)
    with tempfile.TemporaryDirectory(dir=args.out.parent if args.out.parent.exists()
                                     else None) as tmp:
        work = Path(tmp) / "wheels"
        work.mkdir()
        lacking: dict[str, list[str]] = {python: [] for python in pythons}
        for name, version in sorted(packages.items()):
            if name == "sam2":
                build_sam2(version, work)
                missing = []
            else:
                missing = fetch(name, version, work, pythons)
            for python in missing:
                lacking[python].append(name)
            note = f" (no wheel for Python {', '.join(missing)})" if missing else ""
            print(f"gpu-deps: {name}=={version}{note}", flush=True)
        pythons = [python for python in pythons if not lacking[python]]
        if not pythons:
            raise SystemExit(f"gpu-deps: no Python has every wheel: {lacking}")
        wheels = sorted(work.glob("*.whl"))
        wrong = [w.name for w in wheels if MACHINE_OWN.match(canonical(w.name.split("-")[0]))]
        if wrong:
            raise SystemExit(f"gpu-deps: the machine's own packages crept in: {wrong}")
        size = sum(w.stat().st_size for w in wheels) / 2**20
        if size > args.max_mib:
            raise SystemExit(f"gpu-deps: {size:.1f} MiB of wheels, over the {args.max_mib:g} "
                             "MiB limit; carry fewer Pythons (--pythons)")
        (work / "constraints.txt").write_text(
            "# The versions make gpu-deps carried (tools/gpu_deps.py); make gpu-check installs "
            "with them.\n" + "".join(f"{n}=={v}\n" for n, v in sorted(packages.items())))
        if args.out.exists():
            shutil.rmtree(args.out)
        work.rename(args.out)  # the folder appears complete or not at all
    print(f"gpu-deps: {len(wheels)} wheels, {size:.1f} MiB in {args.out}, complete for Python "
          f"{', '.join(pythons)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

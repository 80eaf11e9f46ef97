"""``grader gradescope``: the autograder zip an instructor uploads to a Gradescope assignment.

The zip holds, at its root (Gradescope's requirement): ``setup.sh`` (run once, as root, when
Gradescope builds the image), ``run_autograder`` (run per submission), the grader wheel and
``rubric/`` (the rubric with the support packages and bags it references, see
``grader.rubric.stage``). Everything ``setup.sh`` installs comes from Ubuntu's archive and PyPI.

``setup.sh`` also installs what the sandbox of student code needs (bubblewrap; util-linux's
``setpriv`` and ``unshare`` are in the base image), builds the rubric's support packages into the
image (``grader gradescope-setup``) and ends with ``grader doctor``, whose log lists each
protection as active or not in Gradescope's container. ``--sandbox require`` makes a missing
protection fail the image build and every run instead of a warning in each result.

Assumed image: Gradescope's default base image, Ubuntu 22.04 ("Base" variant). The ROS 2 Jazzy
wheels are built for CPython 3.11 only; Ubuntu 22.04 has ``python3.11`` in its own archive
(universe), so no PPA or downloaded interpreter is needed. Ubuntu 24.04's archive has no 3.11:
there ``setup.sh`` stops with a message naming the 22.04 image.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from grader import __version__
from grader.errors import GraderError
from grader.api import load_rubric
from grader.api.rubrics import CHECKOUT, in_checkout, stage_rubrics
from grader.lms.gradescope import CACHE_DIR

BASE_IMAGE = "Ubuntu 22.04"
PIP_VERSION = "25.1.1"      # the image's own pip (22.0, Ubuntu's python3.11-venv) predates the wheels' metadata
VENV_DIR = "grader-venv"    # under the autograder root

SETUP_SH = r"""#!/usr/bin/env bash
# Gradescope autograder set-up for {lab} ({title}); made by grader {version}.
# Gradescope runs it once, as root, when it builds the autograder image.
#
# Assumes Gradescope's default base image, {base_image} ("Base" variant). Everything comes from
# Ubuntu's archive and PyPI: python3.11 with venv and headers (Ubuntu 22.04's universe component),
# cmake, ninja and a C/C++ compiler; then the grader wheel and, through `grader setup`, ROS 2
# Jazzy as PyPI wheels (built for CPython 3.11 only) and grader's turtlesim interfaces.
set -euo pipefail
ROOT="${{GRADER_AUTOGRADER_ROOT:-/autograder}}"
SOURCE="$(cd "$(dirname "${{BASH_SOURCE[0]}}")" && pwd)"
VENV="$ROOT/{venv}"
PY=python3.11
export GRADER_SANDBOX={sandbox}

need=()
if command -v "$PY" >/dev/null; then
  "$PY" -c 'import ensurepip' 2>/dev/null || need+=(python3.11-venv)
  inc="$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
  [ -f "$inc/Python.h" ] || need+=(python3.11-dev)
else
  need+=(python3.11 python3.11-venv python3.11-dev)
fi
command -v bwrap >/dev/null || need+=(bubblewrap)      # the sandbox of student code
command -v setpriv >/dev/null || need+=(util-linux)
command -v cmake >/dev/null || need+=(cmake)
command -v ninja >/dev/null || need+=(ninja-build)
{{ command -v cc && command -v c++; }} >/dev/null || need+=(build-essential)
if [ ${{#need[@]}} -gt 0 ]; then
  if ! command -v apt-get >/dev/null; then
    echo "setup.sh: needs ${{need[*]}} and there is no apt-get: select the {base_image} base image" >&2
    exit 1
  fi
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  if ! apt-get install -y -qq --no-install-recommends "${{need[@]}}"; then
    echo "setup.sh: apt-get could not install ${{need[*]}}; python3.11 is in {base_image}'s archive:" \
         "select the {base_image} base image in the autograder settings" >&2
    exit 1
  fi
fi

[ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"      # run again (a rebuilt image): keep the venv
"$VENV/bin/python" -m pip install -q --disable-pip-version-check "pip=={pip}"
"$VENV/bin/python" -m pip install -q --disable-pip-version-check "$SOURCE/{wheel}"
"$VENV/bin/grader" setup --wheels
# the rubric's support packages, compiled once into the image instead of once per submission
"$VENV/bin/grader" gradescope-setup --root "$ROOT" --rubric "$SOURCE/{rubric}"
# a live two-process ROS self-test and a sandboxed node: fail the image build, not a submission;
# its log lists which protections of student code work in this container
"$VENV/bin/grader" doctor
"""

RUN_AUTOGRADER = r"""#!/usr/bin/env bash
# Gradescope runs this for every submission: grade $ROOT/submission with the rubric below and
# write $ROOT/results/results.json (grader keeps result.json, report.html and bags in $ROOT/{work}).
# Student code runs in grader's sandbox (as in `grader grade`): it sees nothing of $ROOT/source,
# $ROOT/results or grader's outputs, and only this process writes results.json.
ROOT="${{GRADER_AUTOGRADER_ROOT:-/autograder}}"
export GRADER_SANDBOX={sandbox}
mkdir -p "$ROOT/results"
exec "$ROOT/{venv}/bin/grader" gradescope-run --root "$ROOT" --rubric "$ROOT/source/{rubric}" \
    --cache-dir "$ROOT/{cache}"
"""


def checkout_root() -> Path | None:
    return CHECKOUT if in_checkout() else None


def build_wheel(dest: Path) -> Path:
    """Build the grader wheel from this source checkout with pip (build isolation: the pinned
    build requirements of pyproject.toml)."""
    root = checkout_root()
    if root is None:
        raise GraderError("this grader is installed, not a source checkout, so it cannot build its own "
                          "wheel: pass the wheel you installed it from with --wheel FILE.whl.")
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q",
                           "--disable-pip-version-check", "-w", str(dest), str(root)],
                          capture_output=True, text=True)
    wheels = sorted(dest.glob("grader-*.whl"))
    if proc.returncode != 0 or not wheels:
        tail = "\n".join((proc.stderr or proc.stdout).strip().splitlines()[-15:])
        raise GraderError(f"building the grader wheel from {root} failed:\n{tail}")
    return wheels[-1]


def _add(zf: zipfile.ZipFile, path: Path, arcname: str) -> None:
    info = zipfile.ZipInfo.from_file(path, arcname)     # keeps the mode bits (run_autograder: 0755)
    info.compress_type = zipfile.ZIP_DEFLATED
    with path.open("rb") as fh:
        zf.writestr(info, fh.read())


def write_bundle(rubric_path: Path, out: Path, *, wheel: Path | None = None, sandbox: str = "auto") -> dict:
    """Write the autograder zip; returns a summary (files, lab, items) for the CLI."""
    rubric = load_rubric(rubric_path)
    if sandbox not in ("auto", "require"):
        raise GraderError(f"--sandbox {sandbox}: use auto or require.")
    if wheel is not None and not (wheel.is_file() and wheel.name.endswith(".whl")):
        raise GraderError(f"--wheel {wheel}: not a .whl file.")
    out = Path(out)
    if out.suffix != ".zip":
        raise GraderError(f"-o {out}: the autograder bundle is a .zip file (e.g. -o autograder.zip).")
    with tempfile.TemporaryDirectory(prefix="grader-gradescope-") as tmp:
        stage = Path(tmp) / "bundle"
        stage.mkdir()
        wheel_file = wheel if wheel is not None else build_wheel(Path(tmp) / "wheel")
        shutil.copy2(wheel_file, stage / wheel_file.name)
        staged = stage_rubrics([rubric_path], stage / "rubric")[0]
        rubric_rel = staged.relative_to(stage).as_posix()
        fields = dict(lab=rubric.lab, title=rubric.title, version=__version__, base_image=BASE_IMAGE,
                      venv=VENV_DIR, pip=PIP_VERSION, wheel=wheel_file.name, rubric=rubric_rel,
                      work="grader-out", cache=CACHE_DIR, sandbox=sandbox)
        (stage / "setup.sh").write_text(SETUP_SH.format(**fields))
        (stage / "run_autograder").write_text(RUN_AUTOGRADER.format(**fields))
        for script in ("setup.sh", "run_autograder"):
            (stage / script).chmod(0o755)
        out.parent.mkdir(parents=True, exist_ok=True)
        partial = out.with_name(f".{out.name}.partial")
        with zipfile.ZipFile(partial, "w") as zf:
            for path in sorted(p for p in stage.rglob("*") if p.is_file()):
                _add(zf, path, path.relative_to(stage).as_posix())
        partial.replace(out)
    manual = [i for i in rubric.items if i.kind == "manual"]
    auto = [i for i in rubric.items if i.kind != "manual"]
    return {"zip": out, "lab": rubric.lab, "wheel": wheel_file.name, "rubric": rubric_rel,
            "tests": len(auto), "auto_points": rubric.auto_max,
            "hidden": sum(1 for i in auto if not i.public and i.kind != "integrity"),
            "integrity": sum(1 for i in auto if i.kind == "integrity"),
            "manual": [(i.id, i.points) for i in manual]}

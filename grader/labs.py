"""The labs this grader knows: the rubrics of a source checkout, or those packaged in the wheel.

In a checkout, ``rubrics/`` (next to the ``grader`` package) is the single source. A built wheel
carries a copy under ``grader/_data/``: every rubric with the files it references (support
packages, replayed bags) in the checkout's layout, plus the ``requirements/`` pins that
``grader setup`` installs. ``stage_package_data`` makes that copy; ``setup.py`` calls it at build
time, when only PyYAML is installed, so nothing here imports pandas or rclpy at module level.

``grader labs`` lists them; ``grader check --lab ID`` finds a rubric with ``rubric_for_lab``.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from grader.errors import GraderError
from grader.rubric.load import load_rubric
from grader.rubric.stage import referenced_paths, stage_rubrics

PACKAGE = Path(__file__).resolve().parent
CHECKOUT = PACKAGE.parent
#: what the wheel carries (made by setup.py at build time; absent in a checkout)
PACKAGED_DATA = PACKAGE / "_data"
DATA_DIRS = ("rubrics", "requirements")


@dataclass(frozen=True)
class Lab:
    id: str
    title: str
    points: float          # the rubric's total (manual items included)
    auto_points: float     # what the grader scores by itself
    rubric: Path


def in_checkout() -> bool:
    """True when this grader runs from a source checkout (it has ``rubrics/`` and ``setup.py``)."""
    return (CHECKOUT / "rubrics").is_dir() and (CHECKOUT / "setup.py").is_file()


def data_root() -> Path:
    """The folder holding ``rubrics/`` and ``requirements/``: the checkout, else the wheel's copy."""
    return CHECKOUT if in_checkout() else PACKAGED_DATA


def rubrics_dir() -> Path:
    return data_root() / "rubrics"


def requirements_dir() -> Path:
    return data_root() / "requirements"


def known_labs() -> tuple[list[Lab], list[str]]:
    """Every loadable rubric as a Lab, and one line per rubric that does not load."""
    labs, broken = [], []
    for path in sorted(rubrics_dir().glob("*.yaml")):
        try:
            rub = load_rubric(path)
        except GraderError as exc:
            broken.append(f"{path.name}: {str(exc).splitlines()[0]}")
            continue
        labs.append(Lab(rub.lab, rub.title, float(rub.total if rub.total is not None else rub.total_max),
                        rub.auto_max, path))
    return sorted(labs, key=lambda lab: lab.id), broken     # by id, as `grader labs` lists them


def rubric_for_lab(lab: str) -> Path:
    labs, _broken = known_labs()
    for known in labs:
        if known.id == lab:
            return known.rubric
    names = ", ".join(known.id for known in labs) or "none"
    raise GraderError(f"no rubric for lab {lab!r}; known labs: {names} (see `grader labs`, "
                      f"or pass your own with --rubric FILE).")


def stage_package_data(checkout: Path, dest: Path) -> list[Path]:
    """Copy the checkout's rubrics (with what they reference) and requirement pins into ``dest``.

    ``dest`` is emptied first, so a rubric removed from ``rubrics/`` leaves the next wheel too.
    Returns every source file the copy came from (for the sdist).
    """
    checkout, dest = Path(checkout).resolve(), Path(dest)
    if dest.exists():
        shutil.rmtree(dest)
    rubrics = sorted((checkout / "rubrics").glob("*.yaml"))
    if not rubrics:
        raise GraderError(f"no rubrics in {checkout / 'rubrics'}: a wheel without labs is of no use.")
    stage_rubrics(rubrics, dest, root=checkout)
    requirements = sorted((checkout / "requirements").glob("*.txt"))
    (dest / "requirements").mkdir(parents=True)
    for req in requirements:
        shutil.copy2(req, dest / "requirements" / req.name)
    sources = list(rubrics) + requirements
    for rubric in rubrics:
        for ref in referenced_paths(load_rubric(rubric, analyzers=None)):
            sources += sorted(p for p in ref.rglob("*") if p.is_file()) if ref.is_dir() else [ref]
    return sources

"""Build hooks (the project's metadata is in pyproject.toml).

The wheel must work without the repository: it carries every rubric of ``rubrics/`` with the
support packages and bags each one references, and the ``requirements/`` pins that
``grader setup`` installs. They are copied at build time into ``grader/_data/`` of the build
tree (``grader.labs.stage_package_data``), never into the source tree, so ``rubrics/``,
``fixtures/`` and ``requirements/`` stay the single source. The sdist lists the same source
files, so a wheel built from the sdist (``python -m build``) has them too.
"""

from __future__ import annotations

import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.command.sdist import sdist

HERE = Path(__file__).resolve().parent


def _stage(dest: Path) -> list[Path]:
    sys.path.insert(0, str(HERE))
    try:
        from grader.labs import stage_package_data
    finally:
        sys.path.remove(str(HERE))
    return stage_package_data(HERE, dest)


class BuildPyWithLabs(build_py):
    def run(self) -> None:
        super().run()
        if not self.dry_run:
            _stage(Path(self.build_lib) / "grader" / "_data")


class SdistWithLabs(sdist):
    def make_distribution(self) -> None:
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            sources = _stage(Path(tmp) / "_data")
        self.filelist.extend(str(p.relative_to(HERE)) for p in sources)
        self.filelist.sort()
        self.filelist.remove_duplicates()
        super().make_distribution()


setup(cmdclass={"build_py": BuildPyWithLabs, "sdist": SdistWithLabs})

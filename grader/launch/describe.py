"""``python -m grader.launch.describe FILE [name:=value ...]``: what a Python launch file starts.

Runs in a subprocess of its own (the launch file is student code), with the grader's
``launch``/``launch_ros`` stand-ins first on ``sys.path``, and prints one JSON document:
``{"entities": [...]}`` (see ``grader.launch.entities.describe``) or ``{"error": "..."}`` with
exit code 1.
"""

from __future__ import annotations

import json
import sys
import traceback
from pathlib import Path

API = Path(__file__).resolve().parent / "api"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print("usage: python -m grader.launch.describe FILE [name:=value ...]", file=sys.stderr)
        return 2
    sys.path.insert(0, str(API))
    from grader.launch.entities import LaunchFileError, LaunchUnsupported, describe  # noqa: PLC0415 - launch.describe loads in every scenario child process; launch.entities only on this path

    path = Path(argv[0])
    arguments = dict(a.split(":=", 1) for a in argv[1:] if ":=" in a)
    try:
        entities = describe(path, arguments)
    except (LaunchUnsupported, LaunchFileError) as exc:
        print(json.dumps({"error": str(exc)}))
        return 1
    except Exception as exc:  # noqa: BLE001 - the student's launch file raised
        # the innermost frame of the student's own files (not the grader's, not an installed library's)
        frames = [f for f in traceback.extract_tb(exc.__traceback__) if f.filename.endswith(".py")
                  and not {"grader", "site-packages", "dist-packages"} & set(Path(f.filename).parts)]
        where = f"{Path(frames[-1].filename).name}:{frames[-1].lineno}: " if frames else f"{path.name}: "
        print(json.dumps({"error": f"{where}{type(exc).__name__}: {exc}"}))
        return 1
    print(json.dumps({"entities": entities}, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())

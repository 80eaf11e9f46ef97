"""Run a student's entry point ``module:func`` as if it were its console script (a rubric's
``module:`` process; executables are started as ``ros2 run`` starts them: grader.workspace.executables).

``python -m grader.workspace.launch turtle_control.goal_publisher:main goal_pub --ros-args ...``
sets ``sys.argv`` the way ``ros2 run`` would (script name, then the arguments), imports the
module and calls the function, with the exit code a console script would give.
"""

import importlib
import sys


def main() -> None:
    if len(sys.argv) < 3:
        sys.exit("usage: python -m grader.workspace.launch MODULE[:FUNC] NAME [ARGS...]")
    target, name, args = sys.argv[1], sys.argv[2], sys.argv[3:]
    module_name, _, func_name = target.partition(":")
    sys.argv = [name, *args]
    module = importlib.import_module(module_name)
    func = getattr(module, func_name or "main")
    sys.exit(func())


if __name__ == "__main__":
    main()

"""The subset of ROS 2's ``launch`` / ``launch_ros`` Python API that course launch files use.

Where no ROS 2 ``launch`` package is installed (PyPI wheels have none), a student's launch file
is executed against these classes instead (``grader.launch.describe`` puts thin ``launch`` and
``launch_ros`` packages that re-export them first on ``sys.path``). They do not start anything:
:func:`describe` walks the ``LaunchDescription`` the way ``ros2 launch`` would (launch
arguments, substitutions, conditions, includes, timers) and returns the processes it would
start, which the grader then starts through its own runner, with the same limits and logs as
any student process.

Anything outside the subset raises :class:`LaunchUnsupported` naming the API and the launch
file line, so a student learns what to change instead of getting a silent difference.
"""

from __future__ import annotations

import inspect
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

#: what ``describe`` records for each entity the launch file would start
Described = dict[str, Any]


class LaunchUnsupported(Exception):
    """A launch file uses something the grader's loader does not implement."""


class LaunchFileError(Exception):
    """A launch file that cannot be loaded (syntax, missing function, bad argument)."""


def caller_line() -> str:
    """``file:line`` of the launch-file frame that called into this API (for messages)."""
    here = {Path(__file__).resolve()}
    for frame in inspect.stack()[1:]:
        path = Path(frame.filename).resolve()
        if path in here or "/launch/api/" in str(path) or path.name == "describe.py":
            continue
        return f"{path.name}:{frame.lineno}"
    return "?"


def missing(module: str, name: str) -> Exception:
    """What a stand-in module raises for a name it lacks: AttributeError for Python's own probes
    (``__path__``...), :class:`LaunchUnsupported` for launch API the subset does not have."""
    if name.startswith("__"):
        return AttributeError(name)
    return unsupported(module, name)


def unsupported(module: str, name: str) -> LaunchUnsupported:
    return LaunchUnsupported(f"{caller_line()}: {module}.{name} is not supported by the grader's launch "
                             f"loader (supported: {', '.join(SUPPORTED)}); list the nodes with "
                             "launch_ros.actions.Node instead")


SUPPORTED = ("LaunchDescription", "launch_ros.actions.Node", "DeclareLaunchArgument",
             "LaunchConfiguration", "TextSubstitution", "PathJoinSubstitution",
             "EnvironmentVariable", "ThisLaunchFileDir", "FindPackageShare", "ExecuteProcess",
             "IncludeLaunchDescription", "PythonLaunchDescriptionSource", "TimerAction",
             "SetEnvironmentVariable", "LogInfo", "IfCondition", "UnlessCondition", "ParameterValue")


# ------------------------------------------------------------------------------ substitutions
class Substitution:
    def perform(self, ctx: "Context") -> str:  # pragma: no cover - abstract
        raise NotImplementedError


class TextSubstitution(Substitution):
    def __init__(self, *, text: str = "") -> None:
        self.text = text

    def perform(self, ctx: "Context") -> str:
        return self.text


class LaunchConfiguration(Substitution):
    def __init__(self, variable_name: Any, *, default: Any = None) -> None:
        self.name, self.default, self.at = variable_name, default, caller_line()

    def perform(self, ctx: "Context") -> str:
        name = perform(self.name, ctx)
        if name in ctx.arguments:
            return ctx.arguments[name]
        if self.default is not None:
            return perform(self.default, ctx)
        raise LaunchFileError(f"{self.at}: launch configuration {name!r} has no value (declare it "
                              "with DeclareLaunchArgument(default_value=...) or pass it)")


class PathJoinSubstitution(Substitution):
    def __init__(self, substitutions: Iterable[Any]) -> None:
        self.parts = list(substitutions)

    def perform(self, ctx: "Context") -> str:
        return os.path.join(*[perform(p, ctx) for p in self.parts])


class EnvironmentVariable(Substitution):
    def __init__(self, name: Any, *, default_value: Any = "") -> None:
        self.name, self.default = name, default_value

    def perform(self, ctx: "Context") -> str:
        return ctx.env.get(perform(self.name, ctx), perform(self.default, ctx))


class ThisLaunchFileDir(Substitution):
    def perform(self, ctx: "Context") -> str:
        return str(ctx.file.parent)


class FindPackageShare(Substitution):
    def __init__(self, package: Any) -> None:
        self.package, self.at = package, caller_line()

    def perform(self, ctx: "Context") -> str:
        return package_share(perform(self.package, ctx), self.at)


def package_share(package: str, at: str) -> str:
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory  # noqa: PLC0415 - ament_index_python: ROS, imported where it is used, so this module loads without a ROS install

    try:
        return get_package_share_directory(package)
    except (PackageNotFoundError, OSError, ValueError):     # OSError: no AMENT_PREFIX_PATH at all
        raise LaunchFileError(f"{at}: package {package!r} is not installed "
                              "(not in the submission's build)") from None


def perform(value: Any, ctx: "Context") -> str:
    """A substitution, text, or a list of those (concatenated), as text."""
    if value is None:
        return ""
    if isinstance(value, Substitution):
        return value.perform(ctx)
    if isinstance(value, (list, tuple)):
        return "".join(perform(v, ctx) for v in value)
    if isinstance(value, (str, int, float, bool, Path)):
        return str(value)
    raise LaunchFileError(f"cannot use {type(value).__name__} as a launch substitution")


# -------------------------------------------------------------------------------- conditions
class IfCondition:
    def __init__(self, predicate_expression: Any) -> None:
        self.expr = predicate_expression

    def evaluate(self, ctx: "Context") -> bool:
        return _truth(perform(self.expr, ctx))


class UnlessCondition(IfCondition):
    def evaluate(self, ctx: "Context") -> bool:
        return not super().evaluate(ctx)


def _truth(text: str) -> bool:
    value = text.strip().lower()
    if value in ("true", "1"):
        return True
    if value in ("false", "0"):
        return False
    raise LaunchFileError(f"condition expression {text!r} is neither true nor false")


# ------------------------------------------------------------------------------------ actions
class Action:
    def __init__(self, condition: IfCondition | None = None) -> None:
        self.condition = condition
        self.at = caller_line()

    def applies(self, ctx: "Context") -> bool:
        return self.condition is None or self.condition.evaluate(ctx)


class LaunchDescription:
    def __init__(self, initial_entities: Iterable[Any] | None = None, **_kwargs: Any) -> None:
        self.entities = list(initial_entities or [])

    def add_action(self, action: Any) -> None:
        self.entities.append(action)

    add_entity = add_action


class DeclareLaunchArgument(Action):
    def __init__(self, name: str, *, default_value: Any = None, description: str = "",
                 choices: list[str] | None = None, **kwargs: Any) -> None:
        super().__init__(kwargs.get("condition"))
        self.name, self.default, self.choices = name, default_value, choices


class SetEnvironmentVariable(Action):
    def __init__(self, name: Any, value: Any, **kwargs: Any) -> None:
        super().__init__(kwargs.get("condition"))
        self.name, self.value = name, value


class LogInfo(Action):
    def __init__(self, *, msg: Any = "", **kwargs: Any) -> None:
        super().__init__(kwargs.get("condition"))
        self.msg = msg


class ExecuteProcess(Action):
    def __init__(self, *, cmd: Iterable[Any], name: Any = None, cwd: Any = None,
                 additional_env: dict | None = None, output: Any = None, shell: bool = False,
                 condition: IfCondition | None = None, **_kwargs: Any) -> None:
        super().__init__(condition)
        if shell:
            raise LaunchUnsupported(f"{self.at}: ExecuteProcess(shell=True) is not supported by the "
                                    "grader's launch loader; give cmd as a list")
        self.cmd, self.name, self.env = list(cmd), name, dict(additional_env or {})


class Node(Action):
    """``launch_ros.actions.Node``."""

    def __init__(self, *, executable: Any, package: Any = None, name: Any = None,
                 namespace: Any = None, parameters: Iterable[Any] | None = None,
                 remappings: Iterable[tuple[Any, Any]] | None = None,
                 arguments: Iterable[Any] | None = None, ros_arguments: Iterable[Any] | None = None,
                 output: Any = None, emulate_tty: bool = False, respawn: Any = False,
                 condition: IfCondition | None = None, additional_env: dict | None = None,
                 **kwargs: Any) -> None:
        super().__init__(condition)
        if kwargs:
            raise LaunchUnsupported(f"{self.at}: Node({', '.join(sorted(kwargs))}=...) is not "
                                    "supported by the grader's launch loader")
        self.package, self.executable, self.name, self.namespace = package, executable, name, namespace
        self.parameters = list(parameters or [])
        self.remappings = list(remappings or [])
        self.arguments = list(arguments or [])
        self.ros_arguments = list(ros_arguments or [])
        self.env = dict(additional_env or {})


class TimerAction(Action):
    def __init__(self, *, period: Any, actions: Iterable[Any], **kwargs: Any) -> None:
        super().__init__(kwargs.get("condition"))
        self.period, self.actions = period, list(actions)


class PythonLaunchDescriptionSource:
    def __init__(self, launch_file_path: Any) -> None:
        self.path = launch_file_path


class IncludeLaunchDescription(Action):
    def __init__(self, launch_description_source: Any, *, launch_arguments: Any = None,
                 condition: IfCondition | None = None, **_kwargs: Any) -> None:
        super().__init__(condition)
        if not isinstance(launch_description_source, PythonLaunchDescriptionSource):
            raise LaunchUnsupported(f"{self.at}: only PythonLaunchDescriptionSource includes are "
                                    "supported by the grader's launch loader")
        self.source = launch_description_source
        self.arguments = list(launch_arguments or [])


# ------------------------------------------------------------------------------------ walking
@dataclass
class Context:
    file: Path
    arguments: dict[str, str]
    env: dict[str, str] = field(default_factory=lambda: dict(os.environ))
    delay: float = 0.0
    depth: int = 0


def load_description(path: Path) -> LaunchDescription:
    """Execute a Python launch file and call its ``generate_launch_description()``."""
    if path.suffix in (".xml", ".yaml", ".yml"):
        raise LaunchUnsupported(f"{path.name}: {path.suffix[1:].upper()} launch files are not supported by "
                                "the grader's launch loader; write it as a Python launch file (*.launch.py)")
    source = path.read_text(encoding="utf-8", errors="replace")
    namespace: dict[str, Any] = {"__file__": str(path), "__name__": "__launch_file__"}
    try:
        code = compile(source, str(path), "exec")
    except SyntaxError as exc:
        raise LaunchFileError(f"{path.name}:{exc.lineno}: SyntaxError: {exc.msg}") from None
    exec(code, namespace)  # noqa: S102 - the student's launch file, in a sandboxed subprocess
    fn = namespace.get("generate_launch_description")
    if not callable(fn):
        raise LaunchFileError(f"{path.name}: no generate_launch_description() function")
    description = fn()
    if not isinstance(description, LaunchDescription):
        raise LaunchFileError(f"{path.name}: generate_launch_description() returned "
                              f"{type(description).__name__}, not a LaunchDescription")
    return description


def describe(path: Path, arguments: dict[str, str]) -> list[Described]:
    """Every process the launch file would start, in order, with its start delay."""
    ctx = Context(Path(path).resolve(), dict(arguments))
    out: list[Described] = []
    _walk(load_description(ctx.file).entities, ctx, out)
    return out


def _walk(entities: Iterable[Any], ctx: Context, out: list[Described]) -> None:
    for entity in entities:
        if not isinstance(entity, Action):
            if isinstance(entity, LaunchDescription):
                _walk(entity.entities, ctx, out)
                continue
            raise LaunchUnsupported(f"{ctx.file.name}: {type(entity).__module__}.{type(entity).__name__} "
                                    "is not supported by the grader's launch loader")
        if not entity.applies(ctx):
            continue
        if isinstance(entity, DeclareLaunchArgument):
            if entity.name not in ctx.arguments:
                if entity.default is None:
                    raise LaunchFileError(f"{entity.at}: launch argument {entity.name!r} has no "
                                          "default; the rubric must pass it (launch_arguments)")
                ctx.arguments[entity.name] = perform(entity.default, ctx)
            if entity.choices and ctx.arguments[entity.name] not in entity.choices:
                raise LaunchFileError(f"{entity.at}: launch argument {entity.name!r} is "
                                      f"{ctx.arguments[entity.name]!r}, not one of {entity.choices}")
        elif isinstance(entity, SetEnvironmentVariable):
            ctx.env[perform(entity.name, ctx)] = perform(entity.value, ctx)
        elif isinstance(entity, LogInfo):
            continue
        elif isinstance(entity, TimerAction):
            inner = Context(ctx.file, ctx.arguments, ctx.env, ctx.delay + float(perform(entity.period, ctx)),
                            ctx.depth)
            _walk(entity.actions, inner, out)
        elif isinstance(entity, IncludeLaunchDescription):
            _include(entity, ctx, out)
        elif isinstance(entity, Node):
            out.append(_node(entity, ctx))
        elif isinstance(entity, ExecuteProcess):
            out.append({"kind": "process", "cmd": [perform(c, ctx) for c in entity.cmd],
                        "name": perform(entity.name, ctx) or None, "env": _env(entity.env, ctx),
                        "delay": ctx.delay, "at": entity.at})


def _include(entity: IncludeLaunchDescription, ctx: Context, out: list[Described]) -> None:
    if ctx.depth >= 8:
        raise LaunchFileError(f"{entity.at}: launch files include each other more than 8 deep")
    path = Path(perform(entity.source.path, ctx))
    if not path.is_absolute():
        path = ctx.file.parent / path
    if not path.is_file():
        raise LaunchFileError(f"{entity.at}: included launch file {path} does not exist")
    arguments = dict(ctx.arguments)
    for pair in entity.arguments:
        key, value = pair
        arguments[perform(key, ctx)] = perform(value, ctx)
    inner = Context(path.resolve(), arguments, dict(ctx.env), ctx.delay, ctx.depth + 1)
    _walk(load_description(inner.file).entities, inner, out)


def _env(env: dict, ctx: Context) -> dict[str, str]:
    return {perform(k, ctx): perform(v, ctx) for k, v in env.items()}


def _node(node: Node, ctx: Context) -> Described:
    parameters: list[Any] = []
    for p in node.parameters:
        if isinstance(p, dict):
            parameters.append(_flat_params(p, ctx))
        else:
            parameters.append(perform(p, ctx))          # a YAML parameter file
    remappings = []
    for pair in node.remappings:
        if not (isinstance(pair, (tuple, list)) and len(pair) == 2):
            raise LaunchFileError(f"{node.at}: remappings are (from, to) pairs, got {pair!r}")
        remappings.append([perform(pair[0], ctx), perform(pair[1], ctx)])
    return {"kind": "node", "package": perform(node.package, ctx) or None,
            "executable": perform(node.executable, ctx), "name": perform(node.name, ctx) or None,
            "namespace": perform(node.namespace, ctx) or None, "parameters": parameters,
            "remappings": remappings, "arguments": [perform(a, ctx) for a in node.arguments],
            "ros_arguments": [perform(a, ctx) for a in node.ros_arguments],
            "env": _env(node.env, ctx), "delay": ctx.delay, "at": node.at}


def _flat_params(params: dict, ctx: Context, prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}``, values typed as ``launch_ros`` types them."""
    out: dict[str, Any] = {}
    for key, value in params.items():
        name = prefix + perform(key, ctx)
        if isinstance(value, dict):
            out.update(_flat_params(value, ctx, name + "."))
        else:
            out[name] = _param_value(name, value, ctx)
    return out


def _param_value(name: str, value: Any, ctx: Context) -> Any:
    """launch_ros's rule: text and substitutions are read as YAML ('2.0' is a double, 'true' a
    bool) unless wrapped in ``ParameterValue(value, value_type=str)``; lists are of one type."""
    if isinstance(value, ParameterValue):
        text = perform(value.value, ctx)
        return text if value.value_type is str else _yaml_param(name, text)
    if isinstance(value, (bool, int, float)):
        return value
    if isinstance(value, (str, Substitution)) or (
            isinstance(value, list) and value and all(isinstance(v, Substitution) for v in value)):
        return _yaml_param(name, perform(value, ctx))
    if isinstance(value, (list, tuple)):
        items = [_param_value(name, v, ctx) for v in value]
        if not _scalar_list(items):
            raise LaunchFileError(f"parameter {name!r}: a list parameter needs values of one type "
                                  f"(bool, int, float or str), got {items!r}")
        return items
    raise LaunchFileError(f"parameter {name!r}: {type(value).__name__} is not a parameter value")


def _scalar_list(items: list) -> bool:
    """A list ROS can hold as one parameter: not empty, all bool, all int, all float or all str."""
    return bool(items) and len({type(v) for v in items}) == 1 and isinstance(items[0], (bool, int, float, str))


def _yaml_param(name: str, text: str) -> Any:
    import yaml  # noqa: PLC0415 - yaml: imported where it is used

    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        raise LaunchFileError(f"parameter {name!r}: {text!r} is not valid YAML (wrap a string in "
                              "launch_ros.parameter_descriptions.ParameterValue(value, value_type=str))") from None
    if value is None:
        return ""
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list) and _scalar_list(value):
        return value
    raise LaunchFileError(f"parameter {name!r}: {text!r} is not a bool, int, float, string or list of one of those")


class ParameterValue:
    """``launch_ros.parameter_descriptions.ParameterValue``: ``value_type=str`` keeps text as text."""

    def __init__(self, value: Any, *, value_type: Any = None) -> None:
        self.value, self.value_type = value, value_type

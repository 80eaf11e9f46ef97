"""One-aspect mutants for the collateral-loss audit (``grader rubric collateral``).

Each operator changes one aspect of the reference the way students do, and says which:

* ``rename_node``: the name a node is created with (``super().__init__('x')``, ``Node('x')``,
  ``create_node('x')``) gets ``_renamed`` appended: aspect ``node names``;
* ``log_to_print``: ``self.get_logger().info(text)`` (any level) becomes ``print(text)``:
  aspect ``logging``;
* ``rename_topic`` (``grader.audit.operators``): a topic, service or action name: ``ros names``;
* ``change_timer_period`` (likewise): a timer's period or a rate's frequency: ``timing``.

``ASPECTS`` maps each operator to its aspect; the audit asks which items lost points beyond
those that judge that aspect (``grader.audit.collateral``).
"""

from __future__ import annotations

import ast
from typing import Iterator

from grader.audit.operators import _LOG_METHODS, Edit, Source, _call_name, _walk

#: operator -> the aspect of the code it changes
ASPECTS: dict[str, str] = {"rename_node": "node names", "log_to_print": "logging", "rename_topic": "ros names",
                           "change_timer_period": "timing"}
ASPECT_OPERATORS: tuple[str, ...] = tuple(ASPECTS)
_NODE_CALLS = {"Node", "create_node"}


def _node_name_arg(call: ast.Call) -> ast.Constant | None:
    """The string a node is created with, in ``call`` (None: not a node's creation)."""
    func = call.func
    is_super_init = (isinstance(func, ast.Attribute) and func.attr == "__init__" and isinstance(func.value, ast.Call)
                     and _call_name(func.value) == "super")
    if not is_super_init and _call_name(call) not in _NODE_CALLS:
        return None
    candidates = call.args[:1] + [k.value for k in call.keywords if k.arg == "node_name"]
    for arg in candidates:
        if isinstance(arg, ast.Constant) and isinstance(arg.value, str) and arg.value:
            return arg
    return None


def _rename_node(tree: ast.Module, parents: dict, skip: set, src: Source) -> Iterator[Edit]:
    for node in _walk(tree):
        if isinstance(node, ast.Call) and node not in skip:
            arg = _node_name_arg(node)
            if arg is not None and arg not in skip:
                new = str(arg.value) + "_renamed"
                yield Edit("rename_node", arg, repr(new), f"node name {arg.value!r} -> {new!r}")


def _log_to_print(tree: ast.Module, parents: dict, skip: set, src: Source) -> Iterator[Edit]:
    for node in _walk(tree):
        if not (isinstance(node, ast.Expr) and isinstance(node.value, ast.Call)) or node in skip:
            continue
        call, func = node.value, node.value.func
        if (isinstance(func, ast.Attribute) and func.attr in _LOG_METHODS and isinstance(func.value, ast.Call)
                and _call_name(func.value) == "get_logger" and len(call.args) == 1 and not call.keywords):
            yield Edit("log_to_print", call, f"print({src.segment(call.args[0])})",
                       f"log line printed instead: {src.segment(call)[:60]}")


MAKERS = {"rename_node": _rename_node, "log_to_print": _log_to_print}

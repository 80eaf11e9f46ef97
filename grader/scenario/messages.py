"""ROS messages and the plain values a rubric writes: a type name to its class, a dict of fields
into a message (numbers coerced to each field's type), a message back to JSON-able values for
the driver's events. Used by the driver and its step handlers (``steps.py``).
"""

from __future__ import annotations

import importlib
import math
from typing import Any


def import_type(name: str):
    """``pkg/msg/Name`` (or ``pkg/srv/...``, ``pkg/action/...``) → the Python class."""
    parts = name.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    pkg, kind, cls = parts
    return getattr(importlib.import_module(f"{pkg}.{kind}"), cls)


def fill(msg: Any, values: dict[str, Any]) -> Any:
    """Set (nested) fields of a ROS message from a plain dict; numbers are coerced to the field."""
    types = msg.get_fields_and_field_types()
    for key, value in values.items():
        if key not in types:
            raise ValueError(f"{type(msg).__name__} has no field {key!r} (fields: {', '.join(types)})")
        current = getattr(msg, key)
        if isinstance(value, dict):
            fill(current, value)
        elif isinstance(value, (list, tuple)):
            setattr(msg, key, [float(v) if "float" in types[key] or "double" in types[key] else v
                               for v in value])
        elif isinstance(current, float):
            setattr(msg, key, float(value))
        elif isinstance(current, bool):
            setattr(msg, key, bool(value))
        elif isinstance(current, int):
            setattr(msg, key, int(value))
        else:
            setattr(msg, key, value)
    return msg


def to_plain(msg: Any) -> Any:
    """ROS message → JSON-able dict (for events)."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {k: to_plain(getattr(msg, k)) for k in msg.get_fields_and_field_types()}
    if isinstance(msg, (list, tuple)) or type(msg).__name__ == "array" or hasattr(msg, "tolist"):
        return [to_plain(v) for v in (msg.tolist() if hasattr(msg, "tolist") else msg)]
    if isinstance(msg, float) and not math.isfinite(msg):
        return str(msg)
    return msg

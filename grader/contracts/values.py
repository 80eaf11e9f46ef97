"""``JsonValue``: a value read from JSON or from a recorded ROS message, whose shape its reader
knows (a service request's fields are the service type's, an event's payload is its kind's).

The ground floor is checked with mypy's ``disallow_any_explicit``: this alias is the one place it
admits ``Any``, named, so a reader of such a value can be found and no other ``Any`` hides.
(``object`` would make every reader cast: ``request["x"] + 1`` on an ``object`` does not type.)
"""

from __future__ import annotations

from typing import Any, TypeAlias

JsonValue: TypeAlias = Any  # type: ignore[explicit-any]  # the one named escape (see above)

__all__ = ["JsonValue"]

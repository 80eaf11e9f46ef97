"""The GID of one of the driver's service clients, so a recording can tell the grader's own
service calls from a student's by the call itself, not by when it happened.

Every call to a simulator service is in the bag as ``<service>/_service_event`` (the simulator
runs its services with introspection), and each event carries ``info.client_gid``: the GID of
the client that made the call, as the server saw it. The driver records the GID of the client
it calls with in its ``service_call`` event (:mod:`grader.contracts.events`), and the analyzers
compare the two (:mod:`grader.analyze.provenance`).

Why ``ctypes``: rclpy 7.1.6 has no binding for a client's GID (its ``Client`` offers
``send_request``, ``take_response``, ``configure_introspection``, ``service_name`` and the
``pointer`` of the ``rcl_client_t``; ``take_response``'s header has only the sequence number). The
rmw C API has one, ``rmw_get_gid_for_client`` (what rcl's own client-side introspection uses),
reached from the client's ``rcl_client_t`` with ``rcl_client_get_rmw_handle``. Both live in
``librcl.so``'s dependency tree, which rclpy has already loaded in this process: ``dlopen`` of
the bare name returns that copy (wheels or a sourced ROS alike), so nothing else is loaded.

What the GID says, measured on this machine (rmw_fastrtps_cpp, Fast DDS 2.14): the rmw GID of a
client is its request writer's GUID, while the server's introspection event records the GUID of
the client's response reader (rmw_fastrtps sends the reader's GUID as the request's related
sample identity, so the answer finds the reader). The two differ in the last four bytes (the
RTPS entity id) and share the first twelve: the RTPS GUID prefix, which names the DDS
participant (one per rclpy context). So a call is the driver's when its ``client_gid`` starts
with the GUID prefix of a client the driver recorded: the driver's context belongs to the grader's
scenario process, in which no student code runs, so no student client has that prefix.
"""

from __future__ import annotations

import ctypes
from typing import Any

#: bytes of an RTPS GUID prefix: the participant part of every GID an endpoint of it has
GUID_PREFIX_BYTES = 12


class _Gid(ctypes.Structure):
    # rmw_gid_t: the implementation identifier, then RMW_GID_STORAGE_SIZE bytes (16 in Jazzy;
    # room for 24, the size before Iron, so a larger storage never writes past the buffer)
    _fields_ = [("implementation_identifier", ctypes.c_char_p), ("data", ctypes.c_uint8 * 24)]


def _rcl() -> Any:
    lib = ctypes.CDLL("librcl.so")
    lib.rcl_client_get_rmw_handle.restype = ctypes.c_void_p
    lib.rcl_client_get_rmw_handle.argtypes = [ctypes.c_void_p]
    lib.rmw_get_gid_for_client.restype = ctypes.c_int
    lib.rmw_get_gid_for_client.argtypes = [ctypes.c_void_p, ctypes.POINTER(_Gid)]
    return lib


def client_gid(client: Any) -> list[int]:
    """The rmw GID (16 bytes) of an rclpy ``Client``; raises ``OSError`` when the rmw cannot
    say (the caller records why instead of a GID)."""
    lib = _rcl()
    with client.handle:
        rmw_client = lib.rcl_client_get_rmw_handle(client.handle.pointer)
        if not rmw_client:
            raise OSError("rcl_client_get_rmw_handle returned NULL")
        gid = _Gid()
        ret = lib.rmw_get_gid_for_client(rmw_client, ctypes.byref(gid))
    if ret != 0:
        raise OSError(f"rmw_get_gid_for_client returned {ret}")
    return [int(b) for b in gid.data[:16]]

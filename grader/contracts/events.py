"""The driver's event names, defined once: the driver emits them on ``/grader/events``, the
pipeline and the analyzers read them back from the bag. Pure (no rclpy), so analyzers import it.

Each event is a JSON object ``{"event": <name>, "wall": <epoch s>, ...fields}``; the fields of
each are listed beside it.
"""

from __future__ import annotations

from enum import StrEnum

EVENTS_TOPIC = "/grader/events"
STDOUT_TOPIC = "/grader/stdout"


class Event(StrEnum):
    # scenario
    SCENARIO_START = "scenario_start"        # scenario, domain_id, sim_node
    SCENARIO_END = "scenario_end"            # scenario
    SCENARIO_ABORTED = "scenario_aborted"    # step (its condition never held; on_timeout: abort)
    SCENARIO_INTERRUPTED = "scenario_interrupted"   # (Ctrl-C / SIGTERM of the batch)
    SCENARIO_ERROR = "scenario_error"        # error
    # steps
    STEP_START = "step_start"                # step, action
    STEP_END = "step_end"                    # step, action, ended_by, duration_s
    STEP_SKIPPED = "step_skipped"            # step, reason, exited
    GOAL_SENT = "goal_sent"                  # step, goal [x, y], topic (None: set by a service)
    MESSAGE_SENT = "message_sent"            # step, topic, type, msg, count
    SERVICE_CALL = "service_call"            # step, service, type, request, client_gid (the rmw GID
    #   of the calling client, 16 ints: a service event whose info.client_gid has its first 12
    #   bytes, the DDS participant, is the driver's call; None + client_gid_error when the rmw
    #   could not say; absent in recordings made before it was recorded); asked_for: the
    #   rubric's name when the call went to the name the ``served_by`` node uses instead
    SERVICE_RESPONSE = "service_response"    # step, service, response (None: no response in time), asked_for
    SERVICE_MISSING = "service_missing"      # step, service
    # action: the name the goal went to; asked_for: the rubric's name when that was another
    #   name of the same type (``ActionGoal.by_type``)
    ACTION_SERVER_FOUND = "action_server_found"      # step, action, asked_for
    ACTION_SERVER_MISSING = "action_server_missing"  # step, action
    ACTION_GOAL_SENT = "action_goal_sent"    # step, action, goal
    ACTION_GOAL_RESPONSE = "action_goal_response"    # step, action, accepted (recovered_from_status)
    ACTION_GOAL_UNANSWERED = "action_goal_unanswered"  # step, action, waited_s (no response, no status)
    ACTION_RESULT = "action_result"          # step, action, status, result
    ACTION_CANCEL_SENT = "action_cancel_sent"        # step
    TURTLES_HELD = "turtles_held"            # step, ok (the simulator holds every turtle still)
    TURTLES_RELEASED = "turtles_released"    # step, ok, held_s (the turtles move again)
    REPLAY_START = "replay_start"            # step, topics, count, rate_hz, bag
    REPLAY_END = "replay_end"                # step, count, outputs, paced, resyncs, waited_s, duration_s
    # processes
    NODE_STARTED = "node_started"            # process, of (rubric process), argv (whole), node_name
    NODE_UNAVAILABLE = "node_unavailable"    # process, of, error (why it could not be started), node_name
    NODE_STOPPED = "node_stopped"            # process, returncode
    PROCESS_EXIT = "process_exit"            # process, returncode, stopped_by_grader, timed_out
    STDIN_READY = "stdin_ready"              # process, nodes
    STDIN_LINE = "stdin_line"                # process, line, delivered
    LAUNCH_RESOLVED = "launch_resolved"      # process, launch (the file found), installed, nodes (declared), notes
    PACKAGES = "packages"                    # packages {name: {status, executables, launch_files}} of the build
    LIMIT_HIT = "limit_hit"                  # limit (memory|processes|cpu|output), detail; process, stream (output)
    # the ROS graph
    GRAPH = "graph"                          # nodes, publishers {topic: [node]}, subscribers, services,
    #                                          topic_types {topic: [type]}, servers {service: [node]}, service_types,
    #                                          running [student process alive once the graph was read]

"""What the scenario driver listens to: turtle poses, velocity commands, message counts and
action goal status, each through one subscription per topic of the driver's node.

Split from :mod:`grader.scenario.driver` (one node holds every client and the state the steps
share; what it only *hears* is here, what it asks the graph in ``graph_queries.py``). The state
(``pose_log``, ``counts``, ``commands``...) is the driver's, made in its ``__init__``.
"""

from __future__ import annotations

import collections
from typing import Any, Callable

from grader.scenario.graph_queries import GraphQueries


class TopicWatches(GraphQueries):
    """The driver's subscriptions (a base of :class:`grader.scenario.driver.Driver`; what it asks
    the graph, ``topic_type``, is :class:`GraphQueries`')."""

    clock: Any
    watchdog: Any
    pose: Any
    pose_topic: str | None
    poses: dict[str, Any]
    pose_log: dict[str, Any]
    counts: dict[str, int]
    commands: dict[str, list[Any]]
    goal_status: dict[bytes, int]
    recording_matched: Callable[[str, int], bool] | None
    _counted: set[str]
    _watch: set[str]
    _handlers: dict[str, list[Callable[[Any], None]]]
    _subs: dict[str, Any]

    def _import(self, name: str) -> Any:
        raise NotImplementedError

    def pose_mark(self, topic: str) -> int:
        """The number of the latest pose of ``topic`` received (0 before any)."""
        log = self.pose_log.get(topic)
        return log[-1][0] if log else 0

    def poses_since(self, topic: str, mark: int) -> list[Any]:
        """The poses of ``topic`` received after ``mark`` (see :meth:`pose_mark`), oldest first."""
        return [msg for n, msg in list(self.pose_log.get(topic, ())) if n > mark]

    def watch_pose(self, topic: str = "/turtle1/pose") -> None:
        """Keep the latest turtlesim Pose of ``topic`` in ``poses[topic]`` (and ``pose`` for the
        first one watched)."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install

        if topic in self.pose_log:
            return

        log = self.pose_log.setdefault(topic, collections.deque(maxlen=256))

        def on_pose(msg: Any) -> None:
            self.poses[topic] = msg
            log.append((log[-1][0] + 1 if log else 1, msg))
            if topic not in self._counted:                           # `until: messages` on it counts too
                self.counts[topic] = self.counts.get(topic, 0) + 1
            if self.pose_topic == topic:
                self.pose = msg

        self.pose_topic = self.pose_topic or topic
        self._listen(topic, "turtlesim/msg/Pose", on_pose, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))

    def count_messages(self, topic: str, type_name: str | None, wait_s: float = 3.0) -> None:
        """Count messages on ``topic`` (type from the step, else from the graph).

        Without a type and before the topic exists, the topic is remembered and the subscription
        is made by the tail timer as soon as a publisher appears.
        """
        if topic in self._counted or topic in self.pose_log:     # (its pose subscription counts it)
            return
        type_name = type_name or self.topic_type(topic, wait_s=wait_s)
        if not type_name:
            self._watch.add(topic)
            return
        self._watch.discard(topic)
        self._counted.add(topic)
        self.counts.setdefault(topic, 0)

        def on_msg(_msg: Any) -> None:
            self.counts[topic] += 1
            if self.watchdog is not None:
                self.watchdog.arrived(topic, self.clock.sim_s())

        self._listen(topic, type_name, on_msg, 100)

    def _listen(self, topic: str, type_name: str, handler: Callable[[Any], None], qos: Any) -> None:
        """Hand ``topic``'s messages to ``handler`` too, through one subscription per topic.
        Each watcher used to make its own and skip the topic when another had one: at
        ``--time-scale 4`` the rate watchdog's count of ``/turtle1/cmd_vel`` came first, the
        hand-over never saw a command, and every placed goal of Lab 3's ex2_controller was held
        its full 2 s of wall time (8 s of simulated time) before the turtle was let go."""
        handlers = self._handlers.get(topic)
        if handlers is not None:
            handlers.append(handler)
            return
        handlers = self._handlers[topic] = [handler]

        def on_msg(msg: Any) -> None:
            for h in handlers:
                h(msg)

        self._subs[topic] = self.node.create_subscription(self._import(type_name), topic, on_msg, qos)

    def commands_heard(self, topic: str) -> bool:
        """Every publisher the graph shows on the watched command ``topic`` is matched by the
        driver's subscription (:meth:`watch_commands`) and by the recorder's: a command sent
        from now on is counted by the hand-over and is in the bag."""
        sub = self._subs.get(topic)
        n = self.node.count_publishers(topic)
        if sub is None or n == 0 or sub.get_publisher_count() < n:
            return False
        return self.topic_recorded(topic)

    def topic_recorded(self, topic: str) -> bool:
        """Every publisher the graph shows on ``topic`` is matched by the recorder's
        subscription: what is published on it from now on is in the bag (true at once of a topic
        the scenario does not record). (The graph shows the recorder's subscription before its
        DDS reader has matched a new publisher: in one of three runs of bench_flake a 2 Hz
        publisher's first two messages went unrecorded.)"""
        if self.recording_matched is None:
            return True
        n = self.node.count_publishers(topic)
        return n > 0 and self.recording_matched(topic, n)

    def watch_commands(self, topic: str) -> None:
        """Keep the velocity commands on ``topic`` (a Twist topic) in ``commands[topic]``: how
        many so far and the last one (linear.x, linear.y, angular.z), so a hand-over can tell
        when a controller's commands change with its new goal."""
        if topic in self.commands:
            return
        self.commands[topic] = [0, None]

        def on_cmd(msg: Any) -> None:
            entry = self.commands[topic]
            entry[0] += 1
            entry[1] = (msg.linear.x, msg.linear.y, msg.angular.z)

        self._listen(topic, "geometry_msgs/msg/Twist", on_cmd, 100)

    def watch_action_status(self, action: str) -> None:
        """Keep the latest status of every goal of ``action`` (its ``_action/status`` topic)."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install

        topic = action.rstrip("/") + "/_action/status"
        if topic in self._subs:
            return

        def on_status(msg: Any) -> None:
            for st in msg.status_list:
                self.goal_status[bytes(st.goal_info.goal_id.uuid)] = int(st.status)

        self._subs[topic] = self.node.create_subscription(
            self._import("action_msgs/msg/GoalStatusArray"), topic, on_status,
            QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL))

    def action_status(self, action: str, goal_id: bytes) -> int | None:
        """The last status the server published for ``goal_id`` (None: it never mentioned it)."""
        return self.goal_status.get(goal_id)

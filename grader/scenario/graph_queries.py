"""What the scenario driver asks the ROS graph: nodes, endpoints, types, the recorder's matches.

Split from :mod:`grader.scenario.driver` (one node holds every client and the state the steps
share; what it only *reads* of the graph is here). Every query goes through the driver's own
rclpy node (``self.node``); nothing here sends anything but the ``graph`` event.
"""

from __future__ import annotations

import time
from typing import Any

from grader.contracts.events import Event

#: every node of the grader's own (driver, recorder, stepper) is named with this prefix
GRADER_NODE_PREFIX = "grader_"
#: the service an action server answers goals on, after the action's name
ACTION_GOAL_SERVICE = "/_action/send_goal"


class GraphQueries:
    """The driver's questions to the graph (a base of :class:`grader.scenario.driver.Driver`)."""

    node: Any
    sim_node: str
    processes: dict[str, Any]      # the student processes, by name (ManagedProcess)

    def event(self, event: Event, **fields: Any) -> None:
        raise NotImplementedError

    def topic_type(self, topic: str, wait_s: float = 0.0) -> str | None:
        deadline = time.monotonic() + wait_s
        while True:
            for name, types in self.node.get_topic_names_and_types():
                if name == topic and types:
                    return types[0]
            if time.monotonic() >= deadline:
                return None
            time.sleep(0.1)

    def graph_snapshot(self) -> None:
        """Publish the nodes, and who publishes, subscribes and serves what (with the types):
        integrity checks, "the launch file starts these nodes" and the contract's names found by
        behaviour (the node that serves /set_goal, whatever it is called) need it.

        ``running``: the student processes still alive once the graph was read. The graph lags
        behind a process that has died (DDS forgets its participant a moment later, or a lease
        later), so a node seen in a snapshot counts as running only while a process that could
        have made it was alive: CI once credited a greeter that raised in its constructor with
        "the node is called /my_first_node", from the snapshot taken once its crash ended the step."""
        pubs: dict[str, list[str]] = {}
        subs: dict[str, list[str]] = {}
        names = self.node.get_node_names_and_namespaces()
        nodes = sorted(f"{ns.rstrip('/')}/{n}" for n, ns in names)
        services = sorted(n for n, _ in self.node.get_service_names_and_types())
        topic_types: dict[str, list[str]] = {}
        for topic, types in self.node.get_topic_names_and_types():
            try:
                pubs[topic] = sorted({i.node_name for i in self.node.get_publishers_info_by_topic(topic)})
                subs[topic] = sorted({i.node_name for i in self.node.get_subscriptions_info_by_topic(topic)})
                topic_types[topic] = list(types)
            except Exception:  # noqa: BLE001 - a topic vanishing mid-query is fine
                continue
        servers: dict[str, list[str]] = {}
        service_types: dict[str, list[str]] = {}
        for name, ns in names:
            try:
                offered = self.node.get_service_names_and_types_by_node(name, ns)
            except Exception:  # noqa: BLE001 - the node went away meanwhile
                continue
            for service, types in offered:
                servers.setdefault(service, []).append(name)
                service_types[service] = list(types)
        running = sorted(name for name, proc in self.processes.items() if proc.alive())
        self.event(Event.GRAPH, nodes=nodes, publishers=pubs, subscribers=subs, services=services,
                   topic_types=topic_types, servers={k: sorted(set(v)) for k, v in servers.items()},
                   service_types=service_types, running=running)

    # -- readiness -------------------------------------------------------------------------
    def _student_endpoint(self, topic: str, publisher: bool) -> bool:
        """Does a node other than the grader's (and the sim) publish/subscribe ``topic``?

        Asked per node: endpoint info alone can name an endpoint's node "_NODE_NAME_UNKNOWN_"
        before node discovery completes, which must not count as the student being ready.
        """
        by_node = (self.node.get_publisher_names_and_types_by_node if publisher
                   else self.node.get_subscriber_names_and_types_by_node)
        for name_ns in self.student_nodes():
            try:
                if any(t == topic for t, _ in by_node(*name_ns)):
                    return True
            except Exception:  # noqa: BLE001 - the node went away meanwhile
                continue
        return False

    def student_nodes(self) -> set[tuple[str, str]]:
        return {(n, ns) for n, ns in self.node.get_node_names_and_namespaces()
                if not n.startswith(GRADER_NODE_PREFIX) and n != self.sim_node}

    def recorder_matched(self, name_ns: tuple[str, str]) -> bool:
        """Every topic the node publishes has a grader subscriber (the recorder) matched."""
        try:
            topics = self.node.get_publisher_names_and_types_by_node(*name_ns)
        except Exception:  # noqa: BLE001 - node vanished
            return True
        for topic, _types in topics:
            if topic in ("/rosout", "/parameter_events"):
                continue
            subs = self.node.get_subscriptions_info_by_topic(topic)
            if not any(i.node_name.startswith(GRADER_NODE_PREFIX) for i in subs):
                return False
        return True

    def student_publishes(self, topic: str) -> bool:
        return self._student_endpoint(topic, publisher=True)

    def student_subscribes(self, topic: str) -> bool:
        return self._student_endpoint(topic, publisher=False)

    def service_type(self, name: str) -> str | None:
        """The type a server advertises for service ``name`` (None while there is none)."""
        for service, types in self.node.get_service_names_and_types():
            if service == name and types:
                return types[0]
        return None

    def own_service(self, node: str) -> str | None:
        """The one service node ``node`` (its full name) advertises besides those every node has
        (parameters, type description): the name a student gave the service the lab names, or
        None when the node is not there or serves none or several."""
        ns, _, name = node.rpartition("/")
        try:
            offered = self.node.get_service_names_and_types_by_node(name, ns or "/")
        except Exception:  # noqa: BLE001 - the node is not (or no longer) there
            return None
        own = [service for service, types in offered
               if not any(t.startswith(("rcl_interfaces/", "type_description_interfaces/")) for t in types)]
        return own[0] if len(own) == 1 else None

    def student_action_of_type(self, action_type: str) -> str | None:
        """The one action of ``action_type`` (``pkg/action/Name``) the student's nodes serve, under
        whatever name: a student's other name for the action the lab names, or None when they
        serve none or several of that type."""
        goal_service = action_type + "_SendGoal"
        found = set()
        for name, ns in self.student_nodes():
            try:
                offered = self.node.get_service_names_and_types_by_node(name, ns)
            except Exception:  # noqa: BLE001 - the node is not (or no longer) there
                continue
            found |= {service.removesuffix(ACTION_GOAL_SERVICE) for service, types in offered
                      if service.endswith(ACTION_GOAL_SERVICE) and goal_service in types}
        return found.pop() if len(found) == 1 else None

    def action_available(self, name: str) -> bool:
        return self.service_type(name.rstrip("/") + ACTION_GOAL_SERVICE) is not None

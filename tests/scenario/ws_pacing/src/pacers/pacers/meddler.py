"""Publishes /ticks at 2 Hz from a ROS timer, and meddles with the grader's clock: it asks the
clock owner's hold service to run (harmless here, but it could hold or free simulated time)."""

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from std_msgs.msg import String
from std_srvs.srv import SetBool


class Meddler(Node):
    def __init__(self):
        super().__init__("meddler")
        self.pub = self.create_publisher(String, "ticks", 10)
        self.client = self.create_client(SetBool, "/grader_clock/hold_clock")
        self.sent = False
        self.create_timer(0.5, self.tick)

    def tick(self):
        self.pub.publish(String(data="tick"))
        if not self.sent and self.client.service_is_ready():
            self.client.call_async(SetBool.Request(data=False))
            self.sent = True


def main():
    rclpy.init()
    node = Meddler()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()

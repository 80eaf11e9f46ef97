"""A chaotic controller on ROS time: every 0.05 s it steers turtle1 toward a target that circles
the canvas, with a large gain and no angle wrap, so it turns the long way at the +-pi seam and
runs into walls. A command one tick late on the wall clock sends it along another path; in
lockstep the path is the same in every run."""

import math

import rclpy
from geometry_msgs.msg import Twist
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from turtlesim.msg import Pose


class Chaser(Node):
    def __init__(self):
        super().__init__("chaser")
        self.pose = None
        self.pub = self.create_publisher(Twist, "/turtle1/cmd_vel", 10)
        self.create_subscription(Pose, "/turtle1/pose", self.on_pose, 10)
        self.create_timer(0.05, self.step)

    def on_pose(self, msg):
        self.pose = msg

    def step(self):
        if self.pose is None:
            return
        t = self.get_clock().now().nanoseconds / 1e9
        gx, gy = 5.5 + 4.5 * math.cos(0.7 * t), 5.5 + 4.5 * math.sin(1.3 * t)
        error = math.atan2(gy - self.pose.y, gx - self.pose.x) - self.pose.theta   # no wrap
        cmd = Twist()
        cmd.linear.x = 2.0 * math.hypot(gx - self.pose.x, gy - self.pose.y)
        cmd.angular.z = 6.0 * error
        self.pub.publish(cmd)


def main():
    rclpy.init()
    node = Chaser()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()

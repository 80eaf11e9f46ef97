import sys

import rclpy
from demo_interfaces.action import Drive
from demo_interfaces.msg import Goal
from turtlesim.msg import Pose


def main() -> None:
    rclpy.init()
    node = rclpy.create_node("make_goal")
    goal = Drive.Goal(goal=Goal(x=2.0, y=7.0), start=Pose(x=5.5))
    node.get_logger().info(f"goal x={goal.goal.x} start.x={goal.start.x} tol={goal.goal_tol:.1f} args={sys.argv[1:]}")
    print(f"made goal {goal.goal.x},{goal.goal.y} tol={goal.goal_tol:.1f} argv0={sys.argv[0]}", flush=True)
    node.destroy_node()
    rclpy.shutdown()

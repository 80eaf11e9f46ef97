"""Test node: counts /pose messages, calls /set_pen once, prints a summary and exits."""
import sys
import time

import rclpy
from turtlesim.msg import Pose
from turtlesim.srv import SetPen


def main() -> None:
    rclpy.init()
    node = rclpy.create_node("pose_listener")
    got: list[Pose] = []
    node.create_subscription(Pose, "pose", got.append, 10)
    client = node.create_client(SetPen, "set_pen")
    deadline = time.monotonic() + 20
    while len(got) < 10 and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    if not client.wait_for_service(timeout_sec=10):
        print("no set_pen service", flush=True)
        sys.exit(3)
    future = client.call_async(SetPen.Request(r=10, g=20, b=30, width=4, off=0))
    rclpy.spin_until_future_complete(node, future, timeout_sec=10)
    print(f"received {len(got)} poses; first y={got[0].y if got else None}; "
          f"set_pen done={future.done()}", flush=True)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()

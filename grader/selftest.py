"""Two-process DDS self-test used by `grader doctor`: ``python -m grader.selftest talk|listen``.

The talker publishes ``turtlesim/msg/Pose`` at 50 Hz; the listener exits 0 after 10 messages.
Two separate processes prove discovery, the RMW, and our turtlesim type support all work.
"""

import sys
import time


def main() -> int:
    import rclpy  # noqa: PLC0415 - rclpy: ROS, imported where it is used (this module loads in processes that never use it)
    from turtlesim.msg import Pose  # noqa: PLC0415 - turtlesim.msg: ROS, imported where it is used (this module loads in processes that never use it)

    role = sys.argv[1] if len(sys.argv) > 1 else "listen"
    rclpy.init()
    node = rclpy.create_node(f"grader_selftest_{role}")
    try:
        if role == "talk":
            pub = node.create_publisher(Pose, "grader_selftest", 10)
            count = 0

            def tick() -> None:
                nonlocal count
                count += 1
                pub.publish(Pose(x=float(count), y=1.5))

            node.create_timer(0.02, tick)
            rclpy.spin(node)
            return 0
        got: list[Pose] = []
        node.create_subscription(Pose, "grader_selftest", got.append, 10)
        deadline = time.monotonic() + float(sys.argv[2] if len(sys.argv) > 2 else 15)
        while len(got) < 10 and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
        print(f"received {len(got)} turtlesim/msg/Pose messages", flush=True)
        return 0 if len(got) >= 10 and got[-1].y == 1.5 else 1
    except KeyboardInterrupt:
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())

"""Helpers for tests that spin rclpy executors."""

import time


def spin_until(executor, predicate, timeout_s):
    """Spin `executor` until `predicate()` is true or `timeout_s` passes; return predicate()."""
    deadline = time.monotonic() + timeout_s
    while not predicate() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return predicate()


def call_service(executor, client, srv_type, name, request, timeout_s=30.0):
    """Call a service from node `client` and spin `executor` until the answer comes."""
    cli = client.create_client(srv_type, name)
    assert cli.wait_for_service(timeout_sec=10.0), 'no service %s' % name
    future = cli.call_async(request)
    assert spin_until(executor, future.done, timeout_s), 'no answer from %s' % name
    return future.result()


class RunningNode:
    """hair_sim_node in a private rclpy context, with a client node and an executor."""

    def __init__(self, args):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from hair_sim.ros.node import HairSimNode

        self.context = Context()
        rclpy.init(context=self.context, args=['--ros-args'] + list(args))
        self.node = HairSimNode(context=self.context)
        self.client = rclpy.create_node('hair_sim_test_client', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.client)

    def close(self):
        """Shut everything down."""
        import rclpy
        self.executor.shutdown()
        self.node.destroy_node()
        self.client.destroy_node()
        rclpy.try_shutdown(context=self.context)

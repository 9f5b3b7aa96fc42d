"""Benchmark harness: rosgate (or any rosbridge server) against a bare-tornado ceiling; on rclpy,
beside the Rust rosbridge server and plain rclpy nodes."""

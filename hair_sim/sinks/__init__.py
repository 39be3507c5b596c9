"""Sinks: each turns a HairMesh into what a consumer takes (ROS messages, meshcat, files)."""

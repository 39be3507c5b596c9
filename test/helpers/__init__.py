"""Helper programs that tests start in separate processes."""

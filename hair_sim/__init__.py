"""hair_sim: real-time strip-based hair with U-shape volume (Liang 2003) for ROS 2."""

__version__ = '0.1.0'

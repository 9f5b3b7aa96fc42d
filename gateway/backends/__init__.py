"""The ROS side: one interface (``base``), two implementations (``sim/``, ``rclpy/``), and the
one classifier of blame for errors that cross it (``blame``).

May import: ``protocol`` only. A backend knows nothing of clients, rules or the web.
"""

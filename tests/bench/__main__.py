import sys

from .runner import main

if __name__ == "__main__":
    if sys.argv[1:2] == ["lesson"]:   # the long-lesson run (tests/bench/lesson.py), not the scenarios
        from .lesson import main as lesson
        sys.exit(lesson(sys.argv[2:]))
    if sys.argv[1:2] == ["camera"]:   # cameras for slow clients (tests/bench/camera.py)
        from .camera import main as camera
        sys.exit(camera(sys.argv[2:]))
    if sys.argv[1:2] == ["fleet"]:   # database round trips per command in a fleet (tests/bench/fleet.py)
        from .fleet import main as fleet
        sys.exit(fleet(sys.argv[2:]))
    if sys.argv[1:2] == ["scale"]:   # the class load over 1, 2 and 4 gateways behind nginx (tests/bench/scale.py)
        from .scale import main as scale
        sys.exit(scale(sys.argv[2:]))
    if sys.argv[1:2] == ["history"]:   # the history's cost and reads (tests/bench/history.py)
        from .history import main as history
        sys.exit(history(sys.argv[2:]))
    if sys.argv[1:2] == ["runs"]:   # the run archive's write cost (tests/bench/run_archive.py)
        from .run_archive import main as runs
        sys.exit(runs(sys.argv[2:]))
    if sys.argv[1:2] == ["pyodide"]:   # Python in the IDE page (tests/bench/pyodide.py)
        from .pyodide import main as pyodide
        sys.exit(pyodide(sys.argv[2:]))
    if sys.argv[1:2] == ["foxglove"]:   # the Foxglove path beside the rosbridge path (tests/bench/foxglove.py)
        from .foxglove import main as foxglove
        sys.exit(foxglove(sys.argv[2:]))
    if sys.argv[1:2] == ["stop"]:   # Stop to the robot's zero, blocks and Python (tests/bench/stop.py)
        from .stop import main as stop
        sys.exit(stop(sys.argv[2:]))
    if sys.argv[1:2] == ["suite"]:   # the test suite's CPU per file (tests/bench/suite.py, pytest --cost)
        from .suite import main as suite
        sys.exit(suite(sys.argv[2:]))
    sys.exit(main())

"""The generated Python's Ctrl-C: it stops the robot and ends the program, also when the program
was started with SIGINT ignored (as a shell's background job is, where Python would leave it
ignored and the program could not be stopped but by SIGKILL)."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from tests.support.process import ROOT
from tests.support.ros import RosClient
from tests.support.wait import wait_for

RUNTIME = (ROOT / 'ide' / 'runtime' / 'rosgate_runtime.py').read_text()
DRIVES_ON = RUNTIME + '''

def main():
    rt.log("driving")
    rt.drive("/turtle1/cmd_vel", "geometry_msgs/msg/Twist", {"linear": {"x": 0.5}}, 600)

if __name__ == "__main__":
    run(main)
'''


def ignore_sigint():
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@pytest.mark.parametrize('started', ['plainly', 'with SIGINT ignored'])
def test_ctrl_c_stops_the_robot_and_ends_the_program(start_gateway, tmp_path, started):
    gateway = start_gateway('--robot', 'turtlesim')     # its own turtle: no other test drives it
    ros = RosClient(gateway)
    try:
        cmd = ros.watch('/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')
        program = tmp_path / 'drives_on.py'
        program.write_text(DRIVES_ON)
        proc = subprocess.Popen([sys.executable, str(program), '--url', gateway.ws_url], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True,
                                preexec_fn=ignore_sigint if started != 'plainly' else None)
        try:
            wait_for(lambda: (m := cmd.latest()) and m['linear']['x'] == 0.5, timeout=30, what='the program driving')
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        assert proc.returncode == 0, err
        assert out.splitlines() == ['driving'], out
        wait_for(lambda: cmd.latest()['linear']['x'] == 0, what='a zero after Ctrl-C')
    finally:
        ros.close()

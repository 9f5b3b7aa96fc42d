"""The launcher of a robot-side run: what runs in the box between its start and the program.

It is handed to the box's interpreter as source (``python -I -c SOURCE``; ``SOURCE``, read from this
file) because the box shows none of the gateway's files. Arguments: ``CPU,MEMORY,FILES,PROCS`` (the
rlimits, 0 for none), the port of the relay (0: no relay, a trusted run on the machine's network),
the gateway's unix socket in the box, then the program and its arguments.

It runs between fork and exec of the program: limits first, then the program replaces it. (A
preexec_fn would do the same in the gateway's forked child, which is unsafe with the threads of
the rclpy backend.) Before that it starts the relay that serves the gateway's unix socket on the
box's loopback: it listens first (a program connecting at once finds it there), then a process of
its own (a session of its own, so the SIGINT of a stop reaches the program and not the relay, whose
connection the program may still need to stop the robot) accepts and copies each connection both
ways, while the program starts, so the program never finds its port closed.

Standard library only: it runs in the run's interpreter, which may lack the gateway's packages.
"""

import os
import resource
import socket
import sys
import threading


def pump(a: socket.socket, b: socket.socket) -> None:
    """Copy a to b until a ends; a broken end breaks both."""
    try:
        while True:
            data = a.recv(65536)
            if not data:
                break
            b.sendall(data)
        b.shutdown(socket.SHUT_WR)
    except OSError:
        for end in (a, b):
            try:
                end.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass


def relay(client: socket.socket, path: str) -> None:
    """One connection of the program's, copied both ways to the gateway's unix socket."""
    with client, socket.socket(socket.AF_UNIX) as gateway:
        try:
            gateway.connect(path)
        except OSError:
            return
        back = threading.Thread(target=pump, args=(gateway, client), daemon=True)
        back.start()
        pump(client, gateway)
        back.join()


def serve_relay(port: int, path: str) -> None:
    """Listen on the box's 127.0.0.1:port, then leave a process of a session of its own relaying."""
    server = socket.socket()
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind(('127.0.0.1', port))
    server.listen(64)
    if os.fork() == 0:
        os.setsid()
        if os.fork() == 0:
            while True:
                threading.Thread(target=relay, args=(server.accept()[0], path), daemon=True).start()
        os._exit(0)
    os.wait()
    server.close()


def main(argv: list[str]) -> None:
    cpu, mem, files, procs = (int(v) for v in argv[1].split(','))
    port = int(argv[2])
    if port:
        serve_relay(port, argv[3])
    for limit, value in ((resource.RLIMIT_CPU, (cpu, cpu + 5)), (resource.RLIMIT_AS, (mem, mem)),
                         (resource.RLIMIT_NOFILE, (files, files)), (resource.RLIMIT_NPROC, (procs, procs))):
        if value[0]:
            resource.setrlimit(limit, value)
    os.execv(sys.executable, [sys.executable, '-u', *argv[4:]])


if __name__ == '__main__':
    main(sys.argv)

"""Misbehaving clients for scripts/load: holds SILENT connections that send half a request
head and then nothing, SLOW connections that send a head a byte per second, and STALLED NDJSON
streams that ask for a long run and never read. Each kind reconnects when the server cuts it
off, so the pressure lasts until the process is killed. Prints how many cut-offs it saw."""

import os
import signal
import socket
import sys
import threading
import time

host, port = sys.argv[1], int(sys.argv[2])
silent, slow, stalled = (int(os.environ.get(k, d)) for k, d in
                         (("SILENT", 500), ("SLOW", 50), ("STALLED", 4)))
cut = 0
lock = threading.Lock()


def connect():
    s = socket.create_connection((host, port))
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    return s


def count_cut():
    global cut
    with lock:
        cut += 1


def hold_silent():
    while True:
        try:
            s = connect()
            s.sendall(b"POST /api/v1/simulate HTTP/1.1\r\nHost: x\r\n")
            s.recv(1)  # returns when the server closes the connection
            s.close()
        except OSError:
            pass
        count_cut()


def trickle():
    head = b"GET /api/v1/methods HTTP/1.1\r\nHost: x\r\nX-Slow: " + b"a" * 4096
    while True:
        try:
            s = connect()
            for byte in head:
                s.sendall(bytes([byte]))
                time.sleep(1)
        except OSError:
            pass
        count_cut()


def stall():
    body = b'{"system":"pendulum","method":"modin_3s","h":0.001,"t_end":10000,"output":{"every":10}}'
    request = (b"POST /api/v1/simulate?format=ndjson HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
               b"Content-Length: " + str(len(body)).encode() + b"\r\n\r\n" + body)
    while True:
        try:
            s = connect()
            s.sendall(request)
            time.sleep(3600)  # never reads
        except OSError:
            pass
        count_cut()


def report(*_):
    print(f"attackers: {silent} silent, {slow} slow heads, {stalled} stalled streams; {cut} cut off",
          flush=True)
    os._exit(0)


signal.signal(signal.SIGTERM, report)
for target, n in ((hold_silent, silent), (trickle, slow), (stall, stalled)):
    for _ in range(n):
        threading.Thread(target=target, daemon=True).start()
while True:
    time.sleep(1)

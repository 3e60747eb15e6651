"""EPICS motorPIGCS2's C-867 path over TCP against `host-sim serve`.

Replays tests/epics/motorpigcs2_c867.txt (what the driver sends, in order, and how it reads each
reply; the file says its format) over a socket, reading each reply as the driver's link does: up
to an LF, and on while the text so far ends in a space. host-sim's test
`the_epics_c867_path_runs_unmodified` replays the same file on the core without a socket.

Run: python3 tests/epics/replay.py [path/to/host-sim]   (exit code 0 = pass)
"""
import os
import socket
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
TRANSCRIPT = os.path.join(HERE, "motorpigcs2_c867.txt")
TIMEOUT_S = 5.0  # the driver's own timeout per reply
POLL_S = 0.01


def parse(path):
    """The transcript's steps: (line, command, until seconds or None, rule words)."""
    steps = []
    with open(path, encoding="ascii") as f:
        for n, raw in enumerate(f, 1):
            t = raw.strip()
            if not t or t == "#" or t.startswith("# "):
                continue
            parts = [p.strip() for p in t.split("::")]
            until = None
            if len(parts) == 3:
                word, seconds = parts[1].split()
                assert word == "until", f"line {n}"
                until = float(seconds)
            elif len(parts) != 2:
                raise SystemExit(f"line {n}: `<command> :: <rule>` expected")
            steps.append((n, parts[0], until, parts[-1].split()))
    return steps


def command_bytes(command):
    return {"#4": b"\x04", "#5": b"\x05", "#7": b"\x07"}.get(command, command.encode("ascii") + b"\n")


class Link:
    """The driver's reading of a reply: up to LF, on while the text ends in a space."""

    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=TIMEOUT_S)
        self.buf = b""

    def send(self, data):
        self.sock.sendall(data)

    def line(self):
        while b"\n" not in self.buf:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("server closed the link")
            self.buf += chunk
        line, self.buf = self.buf.split(b"\n", 1)
        return line + b"\n"

    def reply(self):
        data = self.line()
        while data.endswith(b" \n"):
            data += self.line()
        return data

    def nothing_pending(self, wait_s=0.05):
        """True if the board sent nothing (a sent-only command must not be answered)."""
        self.sock.settimeout(wait_s)
        try:
            chunk = self.sock.recv(4096)
            self.buf += chunk
        except socket.timeout:
            pass
        finally:
            self.sock.settimeout(TIMEOUT_S)
        return not self.buf


def after_equals(text):
    if "=" not in text:
        raise ValueError(f"no '=' in {text!r}")
    return float(text.split("=", 1)[1].strip())


def check(rule, reply):
    """None if `reply` (bytes, ending in LF) satisfies `rule` as the driver reads it, else why not."""
    if b"\r" in reply or not reply.endswith(b"\n") or reply.endswith(b" \n"):
        return f"framing: {reply!r}"
    body = reply[:-1]
    kind, args = rule[0], rule[1:]
    if kind == "ready":
        return None if body[:1] == b"\xb1" else f"not ready: {reply!r}"
    text = body.decode("cp1252")
    try:
        if kind == "idn":
            ok = " ".join(args).upper() in text.upper()
        elif kind == "axes":
            ok = [l.rstrip(" ") for l in text.split("\n")] == args
        elif kind == "text":
            ok = bool(text) and "\n" not in text
        elif kind == "err":
            ok = int(text.strip()) == int(args[0])
        elif kind == "=":
            ok = after_equals(text) == float(args[0])
        elif kind == "~":
            ok = abs(after_equals(text) - float(args[0])) <= float(args[1])
        elif kind == ">":
            ok = after_equals(text) > float(args[0])
        elif kind == "int>0":
            x = after_equals(text)
            ok = x >= 1 and x == int(x)
        elif kind == "hex":
            ok = int(text[2:6], 16) & int(args[0], 16) == int(args[1], 16)
        elif kind == "hex5":
            ok = int(text.strip(), 16) & int(args[0], 16) == int(args[1], 16)
        else:
            return f"unknown rule {kind}"
    except ValueError as e:
        return str(e)
    return None if ok else f"{' '.join(rule)} does not hold for {reply!r}"


def start_server(binary):
    proc = subprocess.Popen(
        [binary, "serve", "--tcp", "127.0.0.1:0", "--duration-s", "60"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    line = proc.stdout.readline()  # "listening on 127.0.0.1:PORT"
    if not line.startswith("listening on "):
        proc.kill()
        raise SystemExit(f"host-sim serve did not start: {line!r} {proc.stderr.read()!r}")
    return proc, int(line.rsplit(":", 1)[1])


def main():
    binary = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "target", "release", "host-sim")
    steps = parse(TRANSCRIPT)
    proc, port = start_server(binary)
    t0 = time.monotonic()
    try:
        link = Link(port)
        for n, command, until, rule in steps:
            deadline = time.monotonic() + (until or 0)
            while True:
                link.send(command_bytes(command))
                if rule == ["-"]:
                    why = None if link.nothing_pending() else f"expected nothing, got {link.buf!r}"
                else:
                    why = check(rule, link.reply())
                if why is None:
                    break
                if until is None or time.monotonic() > deadline:
                    raise SystemExit(f"FAIL line {n} `{command}`: {why}")
                time.sleep(POLL_S)
        print(f"EPICS motorPIGCS2 C-867 path: {len(steps)} exchanges as the driver reads them -> ok "
              f"({time.monotonic() - t0:.1f} s)")
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()


if __name__ == "__main__":
    main()

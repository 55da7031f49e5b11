"""Runs of signorini started together with another process, try after try, with the modules loaded once:
`python together.py TRIES READY WAIT -- ARGS...`. Try k (k = 0 .. TRIES-1, `{k}` in READY, WAIT and ARGS
replaced by it) makes the file READY, waits until the file WAIT exists (or, for WAIT given as PATH=TEXT,
until PATH's text starts with TEXT), then runs `signorini ARGS` and prints `try k: STATUS` ('-' for READY or
WAIT: none). Two processes that wait for each other's file start their runs within a millisecond, so a
race between them shows in a few tries (the concurrency tests of maps run it)."""
import sys
import time
from pathlib import Path

from signorini_cli.app import cli

TIMEOUT_S = 120


def wait_for(spec):
    """Until the file exists, or its text starts with the text after '='."""
    path, _, text = spec.partition("=")
    deadline = time.monotonic() + TIMEOUT_S
    while time.monotonic() < deadline:
        try:
            if Path(path).read_text().startswith(text):
                return
        except OSError:
            pass
        time.sleep(0.0005)
    raise TimeoutError(f"{spec} not seen within {TIMEOUT_S} s")


def main(argv):
    tries, ready, wait = int(argv[0]), argv[1], argv[2]
    args = argv[argv.index("--") + 1:]
    for k in range(tries):
        if ready != "-":
            Path(ready.format(k=k)).touch()
        if wait != "-":
            wait_for(wait.format(k=k))
        status = cli.main([arg.format(k=k) for arg in args])
        print(f"try {k}: {status}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])

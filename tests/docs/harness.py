"""The documented commands are the tested commands: run the shell blocks of README.md and
docs/*.md against the simulated cell and compare their output with the document.

Conventions (what a document may contain)
-----------------------------------------
Blocks
    A ```` ```console ```` block is a terminal transcript: a line ``$ CMD`` is a command
    (a line ending in `` \\`` continues on the next), the lines up to the next ``$`` are
    its output as a terminal shows it (stdout and stderr together; a progress line that
    the terminal overwrites in place is not shown). A ```` ```sh ```` (``bash``,
    ``shell``) block is commands only: each must exit 0, its output is not compared.
    Other blocks (python, yaml, json) are not run.
Sessions
    The blocks of one file run in order, in one fresh directory (``examples/`` there is
    the repository's), in one shell environment (``export`` carries over); ``cellcal``
    is ``python -m cellcal`` of this checkout, the terminal is 80 columns wide.
The simulated cell
    ``cellcal sim serve ...`` runs in the background for the rest of the file, with
    ``--port-base P --no-rtde`` appended (free ports of the test's own); the documented
    default ports 15020, 15021, 15700, 15701 (and the ABB robot's 15080, with ``--abb``)
    in later commands become P .. P+4. Its expected output is the URLs it prints.
Comparing output, line by line
    A line ``...`` matches any number of lines (none included); ``[...]`` in a line
    matches any text (a solver's stopping reason, say). Otherwise a line matches
    when its *shape* is the same: numbers (``#``), hashes (``<hex>``: 7+ hex characters
    with a digit and a letter) and times (``2026-11-22 04:25:46``) are masked and runs
    of spaces count as one, so numbers may vary (table columns then move). Trailing
    spaces and blank lines at the end do not count.
Markers
    An HTML comment right before a block's fence, ``<!-- doctest: KEY[=VALUE]; ... -->``:

    ``skip=REASON``
        the block is not run (hardware URLs, installation, the test suite itself);
    ``exit=N``
        every command of the block exits N (default 0);
    ``rel=R; lines=REGEX``
        on output lines matching REGEX, numbers must also agree with the document's
        within the relative tolerance R (numbers followed by ``s``/``ms``, i.e.
        durations, excepted).
"""

from __future__ import annotations

import difflib
import os
import pty
import re
import select
import shlex
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SHELL_LANGS = ("sh", "bash", "shell")
DEFAULT_PORTS = (15020, 15021, 15700, 15701, 15080)

_MARKER = re.compile(r"<!--\s*doctest:\s*(.*?)\s*-->")
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
_HEX = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,}\b")
_TIME = re.compile(r"\d{4}-\d{2}-\d{2}[ T]\d{2}:\d{2}:\d{2}")
_DURATION = re.compile(r"[-+]?\d+(?:\.\d+)?\s?(?:s|ms)\b")


@dataclass
class Command:
    """One command of a block and the output the document shows for it."""

    text: str
    expected: list[str] = field(default_factory=list)
    line: int = 0  # line of the document where the command is


@dataclass
class Block:
    """A fenced shell block of a document."""

    path: Path
    line: int
    lang: str
    commands: list[Command]
    options: dict[str, str]

    @property
    def where(self) -> str:
        return f"{self.path.name}:{self.line}"

    @property
    def skip(self) -> str | None:
        return self.options.get("skip")


def parse_marker(text: str) -> dict[str, str]:
    """``skip=reason; exit=3`` -> {"skip": "reason", "exit": "3"}."""
    out = {}
    for part in text.split(";"):
        part = part.strip()
        if not part:
            continue
        key, _, value = part.partition("=")
        out[key.strip()] = value.strip()
    return out


def _commands(lines: list[tuple[int, str]], console: bool) -> list[Command]:
    cmds: list[Command] = []
    pending: Command | None = None
    for no, line in lines:
        if pending is not None:  # a continued command
            pending.text += "\n" + line
            if not line.rstrip().endswith("\\"):
                pending = None
            continue
        if console and not line.startswith("$ "):
            if cmds:
                cmds[-1].expected.append(line.rstrip())
            continue
        text = line[2:] if console else line
        if not console and (not text.strip() or text.lstrip().startswith("#")):
            continue
        cmd = Command(text.rstrip(), line=no)
        cmds.append(cmd)
        if text.rstrip().endswith("\\"):
            pending = cmd
    return cmds


def parse_blocks(path: Path) -> list[Block]:
    """Every console and shell block of a markdown file, with its marker options."""
    lines = path.read_text().splitlines()
    blocks = []
    i = 0
    while i < len(lines):
        m = re.match(r"^```(\w*)\s*$", lines[i])
        if not m or not m.group(1):
            i += 1
            continue
        lang, start = m.group(1), i
        j = i + 1
        while j < len(lines) and not lines[j].startswith("```"):
            j += 1
        if lang == "console" or lang in SHELL_LANGS:
            options: dict[str, str] = {}
            k = start - 1
            while k >= 0 and _MARKER.fullmatch(lines[k].strip()):
                options = {**parse_marker(_MARKER.fullmatch(lines[k].strip()).group(1)),
                           **options}
                k -= 1
            body = [(n + 1, lines[n]) for n in range(start + 1, j)]
            blocks.append(Block(path, start + 1, lang, _commands(body, lang == "console"),
                                options))
        i = j + 1
    return blocks


# --------------------------------------------------------------------- output
def terminal_text(raw: bytes) -> list[str]:
    """What a terminal shows for ``raw``: ``\\r`` returns to the start of the line (later
    text overwrites), ``\\n`` ends it; trailing spaces stripped."""
    lines: list[str] = []
    cur: list[str] = []
    col = 0
    for ch in raw.decode("utf-8", "replace"):
        if ch == "\n":
            lines.append("".join(cur).rstrip())
            cur, col = [], 0
        elif ch == "\r":
            col = 0
        else:
            if col < len(cur):
                cur[col] = ch
            else:
                cur.append(ch)
            col += 1
    if "".join(cur).strip():
        lines.append("".join(cur).rstrip())
    return lines


def shape(line: str) -> str:
    """A line with times, hashes and numbers masked and spaces collapsed."""
    line = _TIME.sub("<time>", line)
    line = _HEX.sub("<hex>", line)
    line = _NUMBER.sub("#", line)
    return re.sub(r"\s+", " ", line).strip()


def _shape_matches(expected: str, actual: str) -> bool:
    """Shapes equal; ``[...]`` in the expected line matches any text."""
    if "[...]" not in expected:
        return shape(expected) == shape(actual)
    parts = [re.sub(r"\s+", " ", _NUMBER.sub("#", _HEX.sub("<hex>", _TIME.sub("<time>", p))))
             for p in expected.split("[...]")]
    pattern = ".*".join(re.escape(p) for p in parts).strip()
    return re.fullmatch(pattern.replace("\\ ", " ").strip(), shape(actual)) is not None


def _numbers(line: str) -> list[float]:
    line = _TIME.sub(" ", _HEX.sub(" ", _DURATION.sub(" ", line)))
    return [float(v) for v in _NUMBER.findall(line)]


def lines_match(expected: str, actual: str, rel: float | None = None) -> bool:
    if not _shape_matches(expected, actual):
        return False
    if rel is None:
        return True
    if "[...]" in expected:  # numbers in elided text are not compared
        return True
    for e, a in zip(_numbers(expected), _numbers(actual), strict=True):
        if abs(a - e) > rel * max(abs(e), 1e-12):
            return False
    return True


def match_output(expected: list[str], actual: list[str], rel: float | None = None,
                 rel_lines: str | None = None) -> bool:
    """Whether ``actual`` shows what ``expected`` does (``...`` lines match any lines)."""
    exp = _trim(expected)
    act = _trim(actual)
    pattern = re.compile(rel_lines) if rel_lines else None

    def line_ok(e: str, a: str) -> bool:
        tol = rel if pattern is not None and pattern.search(e) else None
        return lines_match(e, a, tol)

    memo: dict[tuple[int, int], bool] = {}

    def go(i: int, j: int) -> bool:
        if (i, j) in memo:
            return memo[i, j]
        if i == len(exp):
            ok = j == len(act)
        elif exp[i].strip() == "...":
            ok = any(go(i + 1, k) for k in range(j, len(act) + 1))
        else:
            ok = j < len(act) and line_ok(exp[i], act[j]) and go(i + 1, j + 1)
        memo[i, j] = ok
        return ok

    return go(0, 0)


def _trim(lines: list[str]) -> list[str]:
    out = [line.rstrip() for line in lines]
    while out and not out[-1]:
        out.pop()
    return out


# ------------------------------------------------------------------- running
def free_port_base(n: int = 4) -> int:
    """A port P with P .. P+n-1 free on loopback (best effort)."""
    for _ in range(200):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            base = s.getsockname()[1]
        if base + n > 65535:
            continue
        socks = []
        try:
            for k in range(n):
                t = socket.socket()
                socks.append(t)
                t.bind(("127.0.0.1", base + k))
            return base
        except OSError:
            continue
        finally:
            for t in socks:
                t.close()
    raise RuntimeError("no free range of ports")


class Session:
    """One document's commands: a directory, a shell environment, a served cell."""

    def __init__(self, workdir: Path) -> None:
        self.dir = workdir
        bindir = workdir / ".bin"
        bindir.mkdir(parents=True)
        wrapper = bindir / "cellcal"
        wrapper.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m cellcal "$@"\n')
        wrapper.chmod(0o755)
        (workdir / "examples").symlink_to(ROOT / "examples")
        self.env_file = workdir / ".env.sh"
        self.env = {**os.environ, "PATH": f"{bindir}{os.pathsep}{os.environ['PATH']}",
                    "PYTHONPATH": str(ROOT), "COLUMNS": "80", "LINES": "40",
                    "PYTHONUNBUFFERED": "1"}
        self.env_file.write_text("")
        self.ports: dict[int, int] = {}
        self.background: list[subprocess.Popen] = []

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        for p in self.background:
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
                try:
                    p.wait(timeout=15)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
            if p.stdout:
                p.stdout.close()
        self.background.clear()

    def _ported(self, text: str) -> str:
        for old, new in self.ports.items():
            text = re.sub(rf":{old}\b", f":{new}", text)
        return text

    def run(self, command: str, timeout: float = 600.0) -> tuple[int, list[str]]:
        """Run one command in the session's shell on a pseudo-terminal; (exit, lines)."""
        if _is_sim_serve(command):
            return 0, self._serve(command)
        script = (f". {shlex.quote(str(self.env_file))}\n{self._ported(command)}\n"
                  f"__rc=$?\nexport -p > {shlex.quote(str(self.env_file))}\nexit $__rc\n")
        master, slave = pty.openpty()
        try:
            proc = subprocess.Popen(["bash", "-c", script], cwd=self.dir, env=self.env,
                                    stdin=subprocess.DEVNULL, stdout=slave, stderr=slave,
                                    start_new_session=True)
        finally:
            os.close(slave)
        raw = b""
        deadline = time.monotonic() + timeout
        try:
            while True:
                left = deadline - time.monotonic()
                if left <= 0:
                    os.killpg(proc.pid, signal.SIGKILL)
                    raise TimeoutError(f"{command!r} did not finish in {timeout:.0f} s")
                if select.select([master], [], [], min(left, 1.0))[0]:
                    try:
                        chunk = os.read(master, 65536)
                    except OSError:  # EIO: every writer closed the terminal
                        break
                    if not chunk:
                        break
                    raw += chunk
                elif proc.poll() is not None:
                    # drain what is left, then stop
                    while select.select([master], [], [], 0.05)[0]:
                        try:
                            chunk = os.read(master, 65536)
                        except OSError:
                            chunk = b""
                        if not chunk:
                            break
                        raw += chunk
                    break
        finally:
            os.close(master)
            rc = proc.wait()
        return rc, terminal_text(raw)

    def _serve(self, command: str) -> list[str]:
        """Start ``cellcal sim serve`` in the background on ports of the session's own; its
        URLs (up to the ``export`` line)."""
        base = free_port_base(len(DEFAULT_PORTS))
        self.ports = {old: base + k for k, old in enumerate(DEFAULT_PORTS)}
        args = [a for a in shlex.split(command, comments=True)[3:] if a != "&"]
        proc = subprocess.Popen([sys.executable, "-m", "cellcal", "sim", "serve", *args,
                                 "--port-base", str(base), "--no-rtde"], cwd=self.dir,
                                env=self.env, stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL)
        self.background.append(proc)
        lines: list[str] = []
        buf = b""
        deadline = time.monotonic() + 60
        fd = proc.stdout.fileno()
        while not (lines and lines[-1].startswith("export ")):
            left = deadline - time.monotonic()
            if left <= 0 or proc.poll() is not None:
                raise RuntimeError(f"{command!r} printed {lines} and no export line")
            if select.select([fd], [], [], min(left, 0.5))[0]:
                chunk = os.read(fd, 4096)
                buf += chunk
                *done, buf = buf.split(b"\n")
                lines += [d.decode().rstrip() for d in done]
        return lines


def _is_sim_serve(command: str) -> bool:
    """``cellcal sim serve ...`` (in the foreground, or with ``&``)."""
    return command.strip().startswith("cellcal sim serve")


def check_block(session: Session, block: Block) -> None:
    """Run a block's commands; AssertionError naming the command and showing a diff."""
    want_rc = int(block.options.get("exit", "0"))
    rel = float(block.options["rel"]) if "rel" in block.options else None
    for cmd in block.commands:
        rc, out = session.run(cmd.text)
        where = f"{block.path.name}:{cmd.line}: $ {cmd.text}"
        if rc != want_rc:
            raise AssertionError(f"{where}\nexit {rc}, expected {want_rc}; output:\n"
                                 + "\n".join(out))
        if block.lang == "console" and not match_output(cmd.expected, out, rel,
                                                        block.options.get("lines")):
            diff = "\n".join(difflib.unified_diff(_trim(cmd.expected), _trim(out),
                                                  "document", "actual", lineterm=""))
            raise AssertionError(f"{where}\noutput differs from the document (numbers, hashes "
                                 f"and times masked):\n{diff}")


def cellcal_argv(command: str) -> list[list[str]]:
    """The argument lists of every ``cellcal ...`` in a command line (up to a pipe,
    redirection or separator), with ``$VAR`` expanded to a placeholder."""
    out = []
    lex = shlex.shlex(command.replace("\\\n", " "), posix=True, punctuation_chars=True)
    lex.whitespace_split = True
    words = list(lex)
    current: list[str] | None = None
    for w in words + [";"]:
        if w in (";", "&&", "||", "|", "&", ">", ">>", "<", "2>", "(", ")"):
            if current:
                out.append(current)
            current = None
            continue
        if w == "cellcal" and current is None:
            current = []
            continue
        if current is not None:
            current.append(re.sub(r"\$\{?\w+\}?", "VALUE", w))
    return out


def main(argv: list[str]) -> int:  # pragma: no cover - a maintainer's tool
    """``python tests/docs/harness.py DOC.md``: run a document's blocks and print what each
    command shows, next to nothing else (to write or update the document's output)."""
    import tempfile

    for name in argv:
        path = Path(name).resolve()
        with tempfile.TemporaryDirectory() as tmp, Session(Path(tmp) / "session") as s:
            for block in parse_blocks(path):
                print(f"==== {block.where} {block.lang} {block.options}")
                if block.skip:
                    continue
                for cmd in block.commands:
                    rc, out = s.run(cmd.text)
                    print(f"$ {cmd.text}" + (f"    [exit {rc}]" if rc else ""))
                    print("\n".join(out))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main(sys.argv[1:]))

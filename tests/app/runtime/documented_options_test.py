#!/usr/bin/python3
"""Every `--option` docs/command-line.md names exists in the `--help` of the command it belongs to.

Usage: documented_options_test.py VOLUME_HAPTICS DOCS/COMMAND-LINE.MD

The oracle is the program itself: each subcommand's `--help` (CLI11) lists its options. An
option belongs to the section it is written in ("## `run`: ..." -> `run --help`; "## The
window" -> `volume-haptics --help`; `bench` -> every benchmark's help; `pacs` -> `pacs echo`,
`find` and `get`), unless it is written after a subcommand's name in the same code span
(`run --check`, `bench table1 --mode`): then it belongs to that subcommand. Sections that name
no command (scene files, exit status, environment) are checked only for such spans.
Exit status: 0 when every option is found, 1 naming each one that is not, 2 on a usage error.
"""

import os
import re
import subprocess
import sys

# A section's title (its first code span) -> the commands whose --help it documents.
SUBCOMMANDS = {
    "run": [["run"]],
    "make-trajectory": [["make-trajectory"]],
    "export": [["export"]],
    "report": [["report"]],
    "bench": [["bench"], ["bench", "table1"], ["bench", "accuracy"], ["bench", "stability"],
              ["bench", "drilling"], ["bench", "bigscan"], ["bench", "render"], ["bench", "memory"]],
    "pacs": [["pacs", "echo"], ["pacs", "find"], ["pacs", "get"]],
}
WINDOW = [[]]  # volume-haptics --help
OPTION = re.compile(r"(?<![\w-])--[A-Za-z][A-Za-z0-9_-]*[A-Za-z0-9]")
CODE_SPAN = re.compile(r"`([^`]+)`")


def help_options(program, command, cache={}):
    """The options `program COMMAND --help` lists (empty when the command has no help)."""
    key = tuple(command)
    if key not in cache:
        env = dict(os.environ)
        env.pop("DISPLAY", None)
        env.pop("WAYLAND_DISPLAY", None)
        env["QT_QPA_PLATFORM"] = "offscreen"
        try:
            out = subprocess.run([program, *command, "--help"], capture_output=True, text=True, env=env,
                                 timeout=180)
            text = out.stdout + out.stderr if out.returncode == 0 else ""
        except (OSError, subprocess.TimeoutExpired) as e:
            sys.exit(f"documented_options_test: cannot run {program} {' '.join(command)} --help: {e}")
        cache[key] = set(OPTION.findall(text))
    return cache[key]


def sections(markdown):
    """(title, body) per "## " section; the text before the first one is titled ""."""
    title, body, result = "", [], []
    for line in markdown.splitlines():
        if line.startswith("## "):
            result.append((title, "\n".join(body)))
            title, body = line[3:], []
        else:
            body.append(line)
    result.append((title, "\n".join(body)))
    return result


def commands_of(title):
    """The commands a section documents: by its title's first code span, or the window's."""
    if title.startswith("The window"):
        return WINDOW
    span = CODE_SPAN.search(title)
    return SUBCOMMANDS.get(span.group(1), []) if span else []


def spans_with_subcommand(body):
    """(commands, option) for each option written after a subcommand's name in a code span or an
    indented line, e.g. `run --check` or `bench table1 --mode all`, and the body without them."""
    pieces = CODE_SPAN.findall(body) + [line.strip() for line in body.splitlines() if line.startswith("    ")]
    # Longest first: a span `run` must not take its name out of a later `run --check`.
    pieces.sort(key=len, reverse=True)
    found = []
    rest = body
    for piece in pieces:
        words = piece.split()
        if words and words[0] == "volume-haptics":
            words = words[1:]
        if not words or words[0] not in SUBCOMMANDS:
            continue
        command = [words[0]]
        if len(words) > 1 and [words[0], words[1]] in SUBCOMMANDS[words[0]]:
            command.append(words[1])
        candidates = [command] if len(command) == 2 or len(SUBCOMMANDS[words[0]]) == 1 else SUBCOMMANDS[words[0]]
        for option in OPTION.findall(" ".join(words[len(command):])):
            found.append((candidates, option))
        rest = rest.replace(piece, "")
    return found, rest


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    program, doc = argv[1], argv[2]
    with open(doc, encoding="utf-8") as f:
        markdown = f.read()
    missing, checked = [], 0
    for title, body in sections(markdown):
        explicit, rest = spans_with_subcommand(body)
        for candidates, option in explicit:
            checked += 1
            if not any(option in help_options(program, c) for c in candidates):
                missing.append(f"{title or '(introduction)'}: {option} is not in `volume-haptics "
                               f"{' '.join(candidates[0])} --help`")
        commands = commands_of(title)
        if not commands:
            continue
        for option in sorted(set(OPTION.findall(rest))):
            checked += 1
            if not any(option in help_options(program, c) for c in commands):
                where = " / ".join(" ".join(["volume-haptics", *c]) for c in commands)
                missing.append(f"{title}: {option} is not in `{where} --help`")
    if missing:
        print(f"documented_options_test: {len(missing)} of {checked} options named in {doc} are not in the "
              "program's --help:")
        for m in missing:
            print("  " + m)
        return 1
    print(f"documented_options_test: all {checked} options named in {doc} are in the program's --help")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

#!/usr/bin/env python3
"""docs/cli.md quotes each command's --help in a ```text block that starts with the command's one-line description
and a `Usage: tessera COMMAND` line. This checks every such block against the binary's own help (exit 1 naming the
command that differs), or with --update rewrites the blocks from it.

Usage: cli_help.py TESSERA_BINARY DOCS_CLI_MD [--update]"""
import re
import subprocess
import sys


def help_text(binary, command):
    out = subprocess.run([binary, command, "--help"], capture_output=True, text=True, check=True).stdout
    # The usage line names the binary as it was invoked; the page names it `tessera`.
    return re.sub(r"^Usage: \S*tessera ", "Usage: tessera ", out, flags=re.M).rstrip("\n")


def main():
    binary, page = sys.argv[1], sys.argv[2]
    update = "--update" in sys.argv[3:]
    text = open(page, encoding="utf-8").read()
    block = re.compile(r"```text\n((?:[^\n]*\n)?Usage: \S*tessera ([\w-]+)[^\n]*\n.*?)```", re.S)
    stale = []

    def fix(m):
        command = m.group(2)
        want = help_text(binary, command)
        if m.group(1).rstrip("\n") != want:
            stale.append(command)
        return "```text\n" + want + "\n```"

    new = block.sub(fix, text)
    if update:
        open(page, "w", encoding="utf-8").write(new)
        print("rewrote", ", ".join(stale) or "nothing")
        return 0
    if stale:
        print(f"{page}: the --help of {', '.join(stale)} differs from the binary's; run "
              f"`python3 tests/docs/cli_help.py build/cli/tessera docs/cli.md --update`")
        return 1
    print("every quoted --help matches")
    return 0


if __name__ == "__main__":
    sys.exit(main())

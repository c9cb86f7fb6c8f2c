#!/usr/bin/env python3
"""Rewrites the verbatim `ehlsim <command> --help` blocks of docs/usage.md from
the binary: the parameters are declared once, in the code, and the docs are
generated from that declaration (ctest Cli.UsageDocumentsTheHelpVerbatim
checks that they agree).

    python3 scripts/sync_usage_help.py [build/apps/ehlsim]
"""
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
COMMANDS = ["impact", "rolling"]


def main():
    binary = sys.argv[1] if len(sys.argv) > 1 else str(ROOT / "build" / "apps" / "ehlsim")
    usage = ROOT / "docs" / "usage.md"
    text = usage.read_text()
    for command in COMMANDS:
        help_text = subprocess.run([binary, command, "--help"], check=True, capture_output=True,
                                   text=True).stdout
        pattern = re.compile(r"(`\./build/apps/ehlsim " + command +
                             r" --help` \(ehlsim [^)]*\), verbatim:\n\n```text\n)(.*?)(```\n)",
                             re.S)
        if not pattern.search(text):
            sys.exit(f"docs/usage.md: no verbatim block for `ehlsim {command} --help`")
        text = pattern.sub(lambda m: m.group(1) + help_text + m.group(3), text, count=1)
    usage.write_text(text)


if __name__ == "__main__":
    main()

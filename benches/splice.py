#!/usr/bin/env python3
"""Splices result fragments into BENCHMARKS.md.

usage: splice.py BENCHMARKS.md FRAGMENT.md...

Each FRAGMENT named NAME.md replaces what stands between `<!-- BEGIN NAME -->` and
`<!-- END NAME -->`. A fragment without its markers in the file is an error (nothing is
written), so a renamed bench cannot silently stop updating the document.
"""
import os
import re
import sys


def main(argv):
    if len(argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    doc_path, fragments = argv[1], argv[2:]
    with open(doc_path, encoding="utf-8") as f:
        doc = f.read()
    for path in fragments:
        name = os.path.splitext(os.path.basename(path))[0]
        with open(path, encoding="utf-8") as f:
            body = f.read().strip("\n")
        pattern = re.compile(
            # An empty block (a new bench's, before its first run) has nothing in between.
            r"(<!-- BEGIN %s -->\n)(?:.*?\n)?(<!-- END %s -->)" % (re.escape(name), re.escape(name)),
            re.S,
        )
        if not pattern.search(doc):
            print(f"{doc_path}: no <!-- BEGIN {name} --> … <!-- END {name} --> block for {path}",
                  file=sys.stderr)
            return 1
        doc = pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(2), doc)
        print(f"{doc_path}: {name} updated")
    with open(doc_path, "w", encoding="utf-8") as f:
        f.write(doc)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

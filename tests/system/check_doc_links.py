#!/usr/bin/env python3
"""Every link of the README and docs/*.md points inside the repository (ctest doc_links):
relative links and images name a file or folder that exists in the repository, an anchor
(#section) names a heading of its page, no link leaves the repository's root, and no page refers
to ../shared (the project's docs must hold what a user needs). Web links (http, https, mailto) are
not followed. Paths into the repository written as code (`tools/ur10_series.sh`, `docs/vcan.md`,
the first word of a command) must exist too, so that a file moved leaves no page citing its old
place; those with placeholders (…, ..., *, CAPITALS) are skipped.

  tests/system/check_doc_links.py REPOSITORY_ROOT
"""
import os
import re
import sys

TOP = r"(?:common|trainer|runtime|lcmtypes|tools|tests|docs|robots|cmake|python|\.ci)"
CODE_PATH = re.compile(r"`(?:\./)?(" + TOP + r"/[^`\s]*)")
LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")


def anchors(path):
    """GitHub's anchors of a Markdown file's headings."""
    found = set()
    in_code = False
    for line in open(path, encoding="utf-8"):
        if line.startswith("```"):
            in_code = not in_code
        m = re.match(r"#{1,6}\s+(.*?)\s*#*\s*$", line)
        if m and not in_code:
            text = re.sub(r"[`*_]|\[([^\]]*)\]\([^)]*\)", r"\1", m.group(1)).strip().lower()
            found.add(re.sub(r"[^\w\- ]", "", text).replace(" ", "-"))
    return found


def check(root):
    root = os.path.realpath(root)
    pages = [os.path.join(root, "README.md")]
    for folder, _, files in os.walk(os.path.join(root, "docs")):
        pages += [os.path.join(folder, f) for f in sorted(files) if f.endswith(".md")]
    problems = []
    links = 0
    for page in pages:
        text = open(page, encoding="utf-8").read()
        name = os.path.relpath(page, root)
        for number, line in enumerate(text.split("\n"), 1):
            if "../shared" in line:
                problems.append("%s:%d: refers to ../shared, outside the repository" % (name, number))
        in_code = False
        for number, line in enumerate(text.split("\n"), 1):
            if line.startswith("```"):
                in_code = not in_code
                continue
            paths = CODE_PATH.findall(line)
            if in_code:  # a command's words: `tools/x.sh ARG`, `D=tests/data/…`
                paths = [w for w in re.split(r"[\s=$\"']+", line.split("#")[0])
                         if re.match(TOP + "/", w)]
            for path in paths:
                path = re.sub(r"(:\d+)*[:,;.)]*$", "", path)
                if re.search(r"\.\.\.|…|\*|\{|<|[A-Z]{3,}", path):
                    continue
                links += 1
                if not os.path.exists(os.path.join(root, path)):
                    problems.append("%s:%d: `%s`: no such file in the repository" % (name, number, path))
            for target in LINK.findall(line):
                links += 1
                if re.match(r"^(https?|mailto):", target):
                    continue
                path, _, anchor = target.partition("#")
                resolved = os.path.realpath(os.path.join(os.path.dirname(page), path)) if path else page
                if os.path.commonpath([resolved, root]) != root:
                    problems.append("%s:%d: %s leaves the repository" % (name, number, target))
                elif not os.path.exists(resolved):
                    problems.append("%s:%d: %s: no such file" % (name, number, target))
                elif anchor and resolved.endswith(".md") and anchor not in anchors(resolved):
                    problems.append("%s:%d: %s: no heading '#%s' in %s"
                                    % (name, number, target, anchor, os.path.relpath(resolved, root)))
    return pages, links, problems


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    pages, links, problems = check(sys.argv[1])
    for problem in problems:
        print(problem)
    print("%d pages, %d links, %d problems" % (len(pages), links, len(problems)))
    sys.exit(1 if problems else 0)

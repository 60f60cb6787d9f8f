#!/usr/bin/env python3
"""The code's shape as docs/architecture.md asks it (ctest code_shape):
- no function in common/, trainer/, runtime/, tools/ or python/ longer than 120 lines (the
  lines from its name to its closing brace, as Universal Ctags reads them), so that one reads
  each at a sitting;
- no index into a mechanism's parameter vector (`parameters[`) outside the Mechanism struct
  and a kind's own files (common/src/mechanisms/, its typed view in
  common/include/stepcal/common/mechanisms/): everybody else uses the kind's named accessors.
Each finding names the file, line and function. Exits 77 (skipped) without ctags.

  tests/system/check_code_shape.py REPOSITORY_ROOT
"""
import json
import os
import re
import shutil
import subprocess
import sys

FOLDERS = ["common", "trainer", "runtime", "tools", "python"]
MAX_FUNCTION_LINES = 120
SOURCE_SUFFIXES = (".cpp", ".hpp", ".h", ".cc")
# The struct that owns the vector, and the folders of each kind's own files.
PARAMETER_INDEX_ALLOWED = (
    "common/include/stepcal/common/mechanisms.hpp",
    "common/src/mechanisms/",
    "common/include/stepcal/common/mechanisms/",
)


def long_functions(root):
    ctags = subprocess.run(
        ["ctags", "--output-format=json", "--fields=+ne", "--kinds-C++=f", "--languages=C++",
         "-f", "-", "-R"] + FOLDERS,
        cwd=root, check=True, capture_output=True, text=True)
    found = []
    for line in ctags.stdout.splitlines():
        tag = json.loads(line)
        if "end" not in tag:
            continue
        length = tag["end"] - tag["line"] + 1
        if length > MAX_FUNCTION_LINES:
            found.append(f"{tag['path']}:{tag['line']}: function {tag['name']} has {length} lines "
                         f"(at most {MAX_FUNCTION_LINES}: split it into named steps)")
    return found


def parameter_indexing(root):
    found = []
    for folder in FOLDERS:
        for directory, _, files in os.walk(os.path.join(root, folder)):
            for name in files:
                if not name.endswith(SOURCE_SUFFIXES):
                    continue
                path = os.path.relpath(os.path.join(directory, name), root)
                if path.startswith(PARAMETER_INDEX_ALLOWED):
                    continue
                with open(os.path.join(root, path), encoding="utf-8") as source:
                    for number, text in enumerate(source, 1):
                        code = text.split("//", 1)[0]
                        if re.search(r"\bparameters\s*\[", code):
                            found.append(f"{path}:{number}: indexes a mechanism's parameters; "
                                         "use the kind's typed view (view<mechanism::Kind>(m))")
    return found


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    if shutil.which("ctags") is None:
        print("code_shape: ctags (universal-ctags) is not installed: skipped")
        return 77
    root = sys.argv[1]
    findings = long_functions(root) + parameter_indexing(root)
    for finding in findings:
        print(finding)
    if findings:
        print(f"code_shape: {len(findings)} finding(s)")
        return 1
    print("code_shape: every function at most", MAX_FUNCTION_LINES, "lines; no parameters[ "
          "outside a kind's own files")
    return 0


if __name__ == "__main__":
    sys.exit(main())

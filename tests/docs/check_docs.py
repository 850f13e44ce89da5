#!/usr/bin/env python3
"""Checks the repository's documents.

1. No text file says how or when the project was made: the phrases below describe the work's own history (numbered
   work steps, working sessions, the build machine's mood on a given day, tracker numbers as history), not the
   project. TLS sessions, HTTP sessions and sessionStorage are not matched.
2. Nothing refers to a sibling checkout through "../" + "shared": scenes live in scenes/course/ and the format in
   docs/scene-format.md.
3. Every relative link in README.md, docs/*.md and core/*/README.md (and deeper core READMEs) names a file that
   exists, and every #anchor names a heading of the target markdown file (GitHub's slug rules).
4. README.md has at most 260 lines.

Usage: check_docs.py [SOURCE_DIR]. Files are those `git ls-files` lists when SOURCE_DIR is a git checkout, else
every file under it (build folders and hidden folders skipped). Exit status 0 when all hold, 1 otherwise.
"""
import os
import re
import subprocess
import sys
import urllib.parse

README_MAX_LINES = 260

# Patterns are assembled from pieces so that this file does not match itself.
_SESSION = "sess" + "ion"
_STOP = "st" + "op"
DIARY = [
    (re.compile(r"\b" + _STOP + r"s? [0-9]+\b(?! ?(s|ms|seconds?|minutes?|bytes?|px|tiles?)\b)", re.I),
     "a numbered work step"),
    (re.compile(r"\bthis " + _SESSION + r"\b", re.I), "a working " + _SESSION),
    (re.compile(r"\b(?:earlier|previous|last|next|later|same|other|second|third|first) " + _SESSION + r"s?\b",
                re.I), "a working " + _SESSION),
    (re.compile(r"\b" + _SESSION + r" [0-9]+\b", re.I), "a working " + _SESSION),
    (re.compile(r"\b(?:slower|faster) VM\b", re.I), "the build machine's speed on a day"),
    (re.compile(r"\bVM (?:was|is|ran) (?:slower|faster)\b", re.I), "the build machine's speed on a day"),
    (re.compile(r"\bhelper's (?:run|build|load|machine)\b|\bother helpers\b|\bhelpers' (?:load|builds?|runs?)\b", re.I),
     "people who worked on it"),
    (re.compile(r"\bissue [0-9]+\b", re.I), "a tracker number as history"),
]
SHARED = re.compile(r"\.\./" + "shared" + r"\b")

TEXT_EXTENSIONS = {
    ".md", ".txt", ".cpp", ".h", ".hpp", ".c", ".cc", ".py", ".sh", ".cmake", ".js", ".css", ".html", ".yaml",
    ".yml", ".json", ".service", ".socket", ".conf", ".toml", ".sbatch", ".in", ".cfg", ".ini", "",
}
SKIP_DIRS = {".git", "build", "build-san", "build-tsan", "node_modules", "__pycache__"}


def tracked_files(root):
    try:
        out = subprocess.run(["git", "-C", root, "ls-files", "-z"], capture_output=True, check=True).stdout
        files = [f for f in out.decode("utf-8", "surrogateescape").split("\0") if f]
        if files:
            return files
    except (OSError, subprocess.CalledProcessError):
        pass
    files = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = [d for d in dirnames if d not in SKIP_DIRS and not d.startswith(".") and
                       not d.startswith("build")]
        for name in filenames:
            files.append(os.path.relpath(os.path.join(dirpath, name), root))
    return files


def read_text(path):
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError:
        return None
    if b"\0" in data[:8192]:
        return None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


def is_text_candidate(rel):
    base = os.path.basename(rel)
    ext = os.path.splitext(base)[1].lower()
    return ext in TEXT_EXTENSIONS or base in ("Dockerfile", "CMakeLists.txt")


def github_slug(heading):
    """GitHub's anchor for a heading: lower case, markup removed, punctuation dropped, spaces to hyphens."""
    text = heading.strip().lower()
    text = re.sub(r"!\[[^\]]*\]\([^)]*\)", "", text)        # images
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)   # links keep their text
    text = re.sub(r"<[^>]+>", "", text)                     # inline HTML
    text = text.replace("`", "").replace("*", "")
    out = []
    for ch in text:
        if ch.isalnum() or ch in "-_" or ch == " ":
            out.append(ch)
    return "".join(out).replace(" ", "-")


def anchors_of(text):
    seen = {}
    anchors = set()
    in_fence = False
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            in_fence = not in_fence
            continue
        if in_fence:
            continue
        m = re.match(r"^(#{1,6})\s+(.*?)\s*#*\s*$", line)
        if not m:
            continue
        slug = github_slug(m.group(2))
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        anchors.add(slug if n == 0 else f"{slug}-{n}")
    for m in re.finditer(r'<a\s+(?:name|id)="([^"]+)"', text):
        anchors.add(m.group(1))
    return anchors


LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")


def links_of(text):
    in_fence = False
    for number, line in enumerate(text.splitlines(), 1):
        if line.lstrip().startswith("```"):
            in_fence = not in_fence
            continue
        if in_fence:
            continue
        stripped = re.sub(r"`[^`]*`", "", line)  # code spans are not links
        for m in LINK.finditer(stripped):
            yield number, m.group(1)


def main():
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else
                           os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
    files = tracked_files(root)
    problems = []

    for rel in sorted(files):
        if not is_text_candidate(rel):
            continue
        text = read_text(os.path.join(root, rel))
        if text is None:
            continue
        for number, line in enumerate(text.splitlines(), 1):
            for pattern, what in DIARY:
                m = pattern.search(line)
                if m:
                    problems.append(f"{rel}:{number}: \"{m.group(0)}\" ({what}): say what holds instead")
            if SHARED.search(line):
                problems.append(f"{rel}:{number}: refers to a sibling checkout; use scenes/course/ and "
                                "docs/scene-format.md")

    documents = [f for f in files if f == "README.md" or re.fullmatch(r"docs/[^/]+\.md", f) or
                 re.fullmatch(r"core/.+/README\.md", f)]
    anchor_cache = {}
    for rel in sorted(documents):
        text = read_text(os.path.join(root, rel))
        if text is None:
            continue
        for number, target in links_of(text):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):  # http:, https:, mailto:
                continue
            path_part, _, anchor = target.partition("#")
            path_part = urllib.parse.unquote(path_part)
            if path_part:
                dest = os.path.normpath(os.path.join(os.path.dirname(os.path.join(root, rel)), path_part))
            else:
                dest = os.path.join(root, rel)
            if not os.path.exists(dest):
                problems.append(f"{rel}:{number}: link to {target}: no such file")
                continue
            if anchor and dest.endswith(".md") and os.path.isfile(dest):
                if dest not in anchor_cache:
                    anchor_cache[dest] = anchors_of(read_text(dest) or "")
                if urllib.parse.unquote(anchor) not in anchor_cache[dest]:
                    problems.append(f"{rel}:{number}: link to {target}: no heading with that anchor")

    readme = read_text(os.path.join(root, "README.md"))
    if readme is not None:
        lines = len(readme.splitlines())
        if lines > README_MAX_LINES:
            problems.append(f"README.md: {lines} lines, more than {README_MAX_LINES}: move detail into docs/")

    for p in problems:
        print(p)
    if problems:
        print(f"{len(problems)} problem(s)")
        return 1
    print(f"documents: {len(files)} files checked, {len(documents)} documents' links resolve")
    return 0


if __name__ == "__main__":
    sys.exit(main())

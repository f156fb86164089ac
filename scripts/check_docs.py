#!/usr/bin/env python3
"""Checks the documentation, from the repository root:

  python3 scripts/check_docs.py

(a) README.md is at most 300 lines;
(b) every relative Markdown link (and image) in README.md, CHANGELOG.md and
    docs/**/*.md points to an existing path inside the repository, and every
    `#anchor` (in the same file or another Markdown file) matches a heading
    there by GitHub's slug rules; http(s) and other external links are not
    fetched;
(c) every docs/*.md page is reachable from docs/index.md through relative
    links;
(d) no work-log numbering ("stop 12", "issues 3") in README.md,
    CHANGELOG.md, docs/, src/ or shaders/.

Prints one line per problem and exits 1, or a one-line summary and exits 0.
Standard library only.
"""

import os
import re
import sys
from collections import deque
from urllib.parse import unquote

ROOT = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))
README_MAX_LINES = 300
LOG_NUMBERING = re.compile(r"\b(stops?|issues?) [0-9]", re.IGNORECASE)
FENCE = re.compile(r"^\s{0,3}(`{3,}|~{3,})")
HEADING = re.compile(r"^\s{0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]*)>?(?:\s+\"[^\"]*\")?\s*\)")
REFERENCE_DEF = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$")
INLINE_CODE = re.compile(r"(`+)(?:.+?)\1")
SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


def rel(path):
    return os.path.relpath(path, ROOT)


def read_lines(path):
    with open(path, encoding="utf-8") as f:
        return f.read().split("\n")


def prose_lines(lines):
    """(line number, text) of the lines outside fenced code blocks, with
    inline code spans blanked out."""
    fence = None
    for number, line in enumerate(lines, 1):
        m = FENCE.match(line)
        if fence is None and m:
            fence = m.group(1)
            continue
        if fence is not None:
            if m and m.group(1)[0] == fence[0] and len(m.group(1)) >= len(fence) \
                    and line.strip() == m.group(1):
                fence = None
            continue
        yield number, INLINE_CODE.sub(lambda s: " " * len(s.group(0)), line)


def slug(text):
    """GitHub's anchor for a heading's text."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)  # links: their text
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML
    text = text.strip().lower()
    text = "".join(c for c in text if c.isalnum() or c in " -_")
    return text.replace(" ", "-")


_anchors = {}


def anchors(path):
    """The anchors of a Markdown file's headings (duplicates numbered as
    GitHub numbers them)."""
    if path not in _anchors:
        seen = {}
        result = set()
        fence = None
        for line in read_lines(path):
            m = FENCE.match(line)
            if fence is None and m:
                fence = m.group(1)
                continue
            if fence is not None:
                if m and line.strip() == m.group(1) and m.group(1)[0] == fence[0]:
                    fence = None
                continue
            h = HEADING.match(line)
            if not h:
                continue
            base = slug(h.group(2))
            n = seen.get(base, 0)
            seen[base] = n + 1
            result.add(base if n == 0 else f"{base}-{n}")
        _anchors[path] = result
    return _anchors[path]


def links(path):
    """(line number, target) of every link and image in a Markdown file."""
    for number, line in prose_lines(read_lines(path)):
        for m in INLINE_LINK.finditer(line):
            yield number, m.group(1)
        m = REFERENCE_DEF.match(line)
        if m:
            yield number, m.group(1)


def markdown_files():
    files = [os.path.join(ROOT, name) for name in ("README.md", "CHANGELOG.md")]
    for base, _, names in os.walk(os.path.join(ROOT, "docs")):
        files += [os.path.join(base, n) for n in sorted(names) if n.endswith(".md")]
    return [f for f in files if os.path.isfile(f)]


def check_links(files, problems):
    """(b); returns the Markdown files each file links to."""
    graph = {}
    for path in files:
        graph[path] = set()
        for number, target in links(path):
            where = f"{rel(path)}:{number}"
            if not target:
                problems.append(f"{where}: empty link")
                continue
            if SCHEME.match(target) or target.startswith("//"):
                continue  # external: not fetched
            file_part, _, anchor = target.partition("#")
            file_part = unquote(file_part)
            if file_part:
                dest = os.path.normpath(os.path.join(os.path.dirname(path), file_part))
            else:
                dest = path
            if os.path.commonpath([dest, ROOT]) != ROOT:
                problems.append(f"{where}: link leaves the repository: {target}")
                continue
            if not os.path.exists(dest):
                problems.append(f"{where}: link to a missing file: {target}")
                continue
            if dest.endswith(".md") and os.path.isfile(dest):
                graph[path].add(dest)
                if anchor and unquote(anchor).lower() not in anchors(dest):
                    problems.append(f"{where}: no heading for #{anchor} in {rel(dest)}")
            elif anchor and not anchor.startswith("L"):
                problems.append(f"{where}: anchor #{anchor} on a file that is not Markdown: {target}")
    return graph


def check_reachable(graph, problems):
    """(c)"""
    index = os.path.join(ROOT, "docs", "index.md")
    if not os.path.isfile(index):
        problems.append("docs/index.md: missing")
        return
    seen = {index}
    queue = deque([index])
    while queue:
        page = queue.popleft()
        for dest in graph.get(page, ()):
            if dest not in seen:
                seen.add(dest)
                queue.append(dest)
    docs = os.path.join(ROOT, "docs")
    for name in sorted(os.listdir(docs)):
        page = os.path.join(docs, name)
        if name.endswith(".md") and page not in seen:
            problems.append(f"docs/{name}: not reachable from docs/index.md")


def check_numbering(problems):
    """(d)"""
    paths = [os.path.join(ROOT, "README.md"), os.path.join(ROOT, "CHANGELOG.md")]
    for top in ("docs", "src", "shaders"):
        for base, _, names in os.walk(os.path.join(ROOT, top)):
            paths += [os.path.join(base, n) for n in sorted(names)]
    for path in paths:
        if not os.path.isfile(path):
            continue
        try:
            lines = read_lines(path)
        except UnicodeDecodeError:
            continue  # not text
        for number, line in enumerate(lines, 1):
            if LOG_NUMBERING.search(line):
                problems.append(f"{rel(path)}:{number}: work-log numbering: {line.strip()}")


def main():
    os.chdir(ROOT)
    problems = []
    readme = os.path.join(ROOT, "README.md")
    if not os.path.isfile(readme):
        problems.append("README.md: missing")
    else:
        n = len(read_lines(readme))
        if read_lines(readme)[-1] == "":
            n -= 1
        if n > README_MAX_LINES:
            problems.append(f"README.md: {n} lines, more than {README_MAX_LINES}")
    files = markdown_files()
    graph = check_links(files, problems)
    check_reachable(graph, problems)
    check_numbering(problems)
    for p in problems:
        print(p)
    if problems:
        return 1
    print(f"docs ok: {len(files)} Markdown files, "
          f"{sum(len(g) for g in graph.values())} links between them, README {n} lines")
    return 0


if __name__ == "__main__":
    sys.exit(main())

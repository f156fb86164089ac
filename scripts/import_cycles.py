#!/usr/bin/env python3
"""Finds import circles between the source files of the crate.

A file depends on another when it names an item defined there: through
`use`, or a path in its code (`crate::a::B`, `super::b::C`, or a path
through a name it imported). Re-exports are followed to the file that
defines the item, so a module file that only re-exports its children is
not a hub. Comments, strings and module declarations are not dependencies.

The library (src/lib.rs) and the command line (src/main.rs, src/cli/) are
two crates and are checked apart. Prints each circle as a chain of files
and exits 1 when there is any; `--graph` also prints every dependency.

Usage: python3 scripts/import_cycles.py [--graph] [SRC_DIR]
"""

import os
import re
import sys

ITEM = re.compile(
    r"^(?:pub(?:\([^)]*\))?\s+)?(?:(?:async|unsafe|const|extern\s+\"C\")\s+)*"
    r"(fn|struct|enum|trait|const|static|type|union|mod)\s+([A-Za-z_]\w*)"
)
MACRO = re.compile(r"macro_rules!\s*([A-Za-z_]\w*)")
PATH = re.compile(r"(?<![\w:])(crate|super|self|[A-Za-z_]\w*)((?:::[A-Za-z_]\w*)+)")


def strip(text):
    """The code without comments, strings and char literals (same lines)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            depth, i = 1, i + 2
            while i < n and depth:
                if text.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif text.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    if text[i] == "\n":
                        out.append("\n")
                    i += 1
        elif c == "r" and re.match(r'r#*"', text[i:i + 10]) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = re.match(r'r(#*)"', text[i:])
            end = '"' + m.group(1)
            j = text.find(end, i + len(m.group(0)))
            j = n if j < 0 else j + len(end)
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j + 1
        elif c == "'" and re.match(r"'(\\.|[^\\'])'", text[i:i + 4]) or text.startswith("'\\u{", i):
            j = text.find("'", i + 2)
            out.append("' '")
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def inline_modules(code):
    """(start, end, name) of every `mod name { ... }` block in `code`."""
    out = []
    for m in re.finditer(r"\bmod\s+([A-Za-z_]\w*)\s*\{", code):
        depth, i = 1, m.end()
        while i < len(code) and depth:
            depth += {"{": 1, "}": -1}.get(code[i], 0)
            i += 1
        out.append((m.end(), i, m.group(1)))
    return out


def nesting(blocks, pos):
    """The inline modules around position `pos`, outermost first."""
    return tuple(name for start, end, name in blocks if start <= pos < end)


def use_trees(code):
    """(position, [(path segments, alias)]) for every `use` declaration."""
    for m in re.finditer(r"(?:^|[;{}\s])((?:pub(?:\([^)]*\))?\s+)?)use\s+([^;]+);", code):
        yield m.start(2), list(expand(m.group(2).replace("\n", " ")))


def expand(tree, prefix=()):
    tree = tree.strip()
    brace = tree.find("{")
    if brace < 0:
        alias = None
        if " as " in tree:
            tree, alias = [s.strip() for s in tree.split(" as ")]
        segs = tuple(s for s in tree.split("::") if s)
        full = prefix + segs
        if full and full[-1] == "self":
            full = full[:-1]
        if full:
            yield full, alias or full[-1]
        return
    head = tuple(s for s in tree[:brace].split("::") if s)
    body = tree[brace + 1:tree.rfind("}")]
    depth, start = 0, 0
    for i, c in enumerate(body + ","):
        if c == "{":
            depth += 1
        elif c == "}":
            depth -= 1
        elif c == "," and depth == 0:
            part = body[start:i].strip()
            if part:
                yield from expand(part, prefix + head)
            start = i + 1


class Crate:
    def __init__(self, src, root, only=None):
        self.files = {}  # module path (tuple) -> file
        self.defs = {}  # file -> item names defined there
        self.uses = {}  # file -> {alias: full path}
        self.code = {}
        self.macros = {}  # exported macro name -> file
        for dirpath, _, names in os.walk(src):
            for name in names:
                if not name.endswith(".rs"):
                    continue
                path = os.path.join(dirpath, name)
                rel = os.path.relpath(path, src)
                if only and not only(rel):
                    continue
                parts = rel[:-3].split(os.sep)
                if parts[-1] == "mod" or rel == root:
                    parts = parts[:-1]
                if rel == root:
                    parts = []
                self.files[tuple(parts)] = rel
        # `#[path = "..."] mod name;` puts a file elsewhere at that module.
        for mod, rel in list(self.files.items()):
            text = open(os.path.join(src, rel), encoding="utf-8").read()
            for m in re.finditer(r'#\[path\s*=\s*"([^"]+)"\]\s*(?:#\[[^\]]*\]\s*)*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*;', text):
                target = os.path.normpath(os.path.join(os.path.dirname(rel), m.group(1)))
                self.files[mod + (m.group(2),)] = target
        for mod, rel in self.files.items():
            text = open(os.path.join(src, rel), encoding="utf-8").read()
            code = strip(text)
            self.code[rel] = code
            names = set()
            for line in code.splitlines():
                m = ITEM.match(line.strip()) if not line.startswith((" ", "\t")) else None
                if m:
                    names.add(m.group(2))
            for m in re.finditer(r"#\[macro_export\]\s*macro_rules!\s*([A-Za-z_]\w*)", code):
                self.macros[m.group(1)] = rel
            for m in MACRO.finditer(code):
                names.add(m.group(1))
            self.defs[rel] = names
            aliases = {}
            blocks = inline_modules(code)
            for pos, leaves in use_trees(code):
                inner = nesting(blocks, pos)
                for full, alias in leaves:
                    if not inner:
                        aliases[alias] = self.absolute(mod, full)
            self.uses[rel] = aliases

    def absolute(self, mod, segs):
        """`segs` as a path from the crate root, seen from module `mod`."""
        segs = list(segs)
        base = list(mod)
        if segs[0] == "crate":
            return tuple(segs[1:])
        if segs[0] in ("self", "super"):
            while segs and segs[0] in ("self", "super"):
                if segs.pop(0) == "super":
                    base = base[:-1]
            return tuple(base + segs)
        if tuple(base + segs[:1]) in self.files:
            return tuple(base + segs)
        return None  # another crate, or std

    def file_path(self, fmod, path):
        """`path` with the file's own inline modules dropped (they are the file)."""
        return path

    def resolve(self, path, seen=()):
        """The file that defines what `path` names (None: outside the crate)."""
        if path is None or path in seen:
            return None
        seen = seen + (path,)
        if len(path) == 1 and path[0] in self.macros:
            return self.macros[path[0]]
        k = len(path)
        while k > 0 and path[:k] not in self.files:
            k -= 1
        if k == 0 and () not in self.files:
            return None
        rel = self.files[path[:k]]
        if k == len(path):
            return None  # a module itself: only what is used through it counts
        name = path[k]
        if name in self.defs[rel]:
            return rel
        target = self.uses[rel].get(name)
        if target is not None:
            return self.resolve(target + path[k + 1:], seen) or rel
        if k == 0 and name in self.macros:
            return self.macros[name]
        return rel

    def edges(self):
        out = {rel: set() for rel in self.files.values()}
        for fmod, rel in self.files.items():
            code = self.code[rel]
            blocks = inline_modules(code)
            # The paths inside `use` are handled apart (same length kept).
            body = re.sub(
                r"(?:pub(?:\([^)]*\))?\s+)?use\s+[^;]+;", lambda m: " " * len(m.group(0)), code
            )
            targets = []
            for pos, leaves in use_trees(code):
                mod = fmod + nesting(blocks, pos)
                for full, _ in leaves:
                    if full[-1] == "*":
                        ab = self.absolute(mod, full[:-1])
                        ab = ab[: len(fmod)] if ab is not None and ab[: len(fmod)] == fmod else ab
                        if ab is not None and ab in self.files:
                            targets.append(self.files[ab])
                        continue
                    targets.append(self.resolve(self.file_path(fmod, self.absolute(mod, full))))
            for m in PATH.finditer(body):
                mod = fmod + nesting(blocks, m.start())
                head, rest = m.group(1), m.group(2).split("::")[1:]
                if head in ("crate", "super", "self"):
                    targets.append(self.resolve(self.file_path(fmod, self.absolute(mod, [head] + rest))))
                elif head in self.uses[rel]:
                    base = self.uses[rel][head]
                    if base is not None:
                        targets.append(self.resolve(base + tuple(rest)))
                elif tuple(mod) + (head,) in self.files:
                    targets.append(self.resolve(tuple(mod) + (head,) + tuple(rest)))
            for m in re.finditer(r"(?<![\w:])([A-Za-z_]\w*)!", body):
                if m.group(1) in self.macros:
                    targets.append(self.macros[m.group(1)])
            for t in targets:
                if t and t != rel:
                    out[rel].add(t)
        return out


def circles(graph):
    """Strongly connected components of more than one file (Tarjan)."""
    index, low, stack, on, comps, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return comps


def a_cycle(graph, comp):
    """One circle through the component's first file, as a list of files."""
    inside = set(comp)
    start = comp[0]
    prev = {start: None}
    queue = [start]
    while queue:
        v = queue.pop(0)
        for w in sorted(graph[v] & inside):
            if w == start:
                path = [v]
                while prev[path[-1]] is not None:
                    path.append(prev[path[-1]])
                return list(reversed(path)) + [start]
            if w not in prev:
                prev[w] = v
                queue.append(w)
    return comp


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    src = args[0] if args else "src"
    crates = [
        ("library", Crate(src, "lib.rs", lambda r: r != "main.rs" and not r.startswith("cli" + os.sep))),
        ("command line", Crate(src, "main.rs", lambda r: r == "main.rs" or r.startswith("cli" + os.sep))),
    ]
    found = 0
    for name, crate in crates:
        graph = crate.edges()
        if "--graph" in sys.argv:
            for v in sorted(graph):
                for w in sorted(graph[v]):
                    print(f"{v} -> {w}")
        for comp in circles(graph):
            found += 1
            print(f"circle in the {name} ({len(comp)} files): " + " -> ".join(a_cycle(graph, comp)))
            print("    files: " + ", ".join(comp))
    if found:
        sys.exit(1)
    total = sum(len(c.files) for _, c in crates)
    print(f"no import circle among {total} files")


if __name__ == "__main__":
    main()

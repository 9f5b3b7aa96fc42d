"""The pages' modules, read as text: one module script per page, no top-level await (but in a leaf), no import
cycle, every relative specifier naming a file that is there, no folder of ide/js over 20 modules. WebKit left the teleop page unstarted when a module of its graph failed to evaluate, and
several module scripts sharing imports (or a cycle, or a top-level await) make what a page shows
hang on the order an engine evaluates them in; one entry that imports and mounts the rest does not
(ide/README.md, "One module per page"). The pages themselves run in three engines in
test_engines.py."""

from __future__ import annotations

import re
from pathlib import Path

IDE = Path(__file__).resolve().parents[2] / "ide"
MODULE_SCRIPT = re.compile(r'<script\s+type="module"\s+src="([^"]+)"')
IMPORT = re.compile(r"""(?:^|\n)\s*(?:import|export)\s[^;]*?from\s+['"](\.{1,2}/[^'"]+)['"]"""
                    r"""|(?:^|\n)\s*import\s+['"](\.{1,2}/[^'"]+)['"]""")
SOURCES = sorted(p for d in ("js", "runtime", "generators") for p in (IDE / d).rglob("*.js"))   # js/inspect/ too


def imports(path: Path) -> list[Path]:
    text = path.read_text()
    return [(path.parent / (a or b)).resolve() for a, b in IMPORT.findall(text)]


def test_each_page_has_one_module_entry():
    pages = sorted(IDE.glob("*.html"))
    assert {p.name for p in pages} >= {"index.html", "teleop.html", "class.html", "twin.html"}
    entries = {p.name: MODULE_SCRIPT.findall(p.read_text()) for p in pages}
    assert entries == {"class.html": ["js/class/main.js"], "index.html": ["js/ide/main.js"],
                       "inspect.html": ["js/inspect/main.js"], "teleop.html": ["js/teleop/main.js"],
                       "twin.html": ["js/twin/main.js"]}
    for p in pages:   # and no inline module either
        assert len(re.findall(r'type="module"', p.read_text())) == 1, p.name


def test_shared_pieces_are_mounted_by_the_entries():
    """recorder.js and booking.js do nothing on import: the entry that uses them mounts them."""
    for name, mount in (("lab/recorder.js", "mountRecorder"), ("lab/booking.js", "mountBooking")):
        text = (IDE / "js" / name).read_text()
        assert f"export function {mount}(" in text
        assert not re.search(r"^(?:const|let)\s+\w+\s*=\s*document\.", text, re.M), name
    for entry, mounts in (("ide/main.js", ["mountRecorder", "mountBooking"]),
                          ("teleop/main.js", ["mountRecorder", "mountBooking"]), ("class/main.js", ["mountBooking"])):
        text = (IDE / "js" / entry).read_text()
        for mount in mounts:   # at the entry's top level, the part kept in the page's state
            assert re.search(rf"^(?:\w+\.\w+ = )?{mount}\(\);", text, re.M), (entry, mount)


def test_no_top_level_await():
    """Except in a leaf: i18n.js (it imports nothing) awaits its texts, so every module that imports
    it runs after them, which is the module graph's own order in every engine (test_engines.py runs
    the pages, Spanish ones in test_languages.py)."""
    for path in SOURCES:
        if path.name == "i18n.js":
            assert imports(path) == [], "i18n.js awaits at its top level: it must stay a leaf"
            continue
        for n, line in enumerate(path.read_text().splitlines(), 1):
            # the house style indents every body: an await at column 0 (or in a top-level
            # declaration) is the module's own
            assert not re.match(r"(?:(?:export\s+)?(?:const|let|var)\s[^=]*=\s*)?await\b", line), \
                f"{path.relative_to(IDE)}:{n}: top-level await"


def test_no_import_cycle():
    graph = {p.resolve(): imports(p) for p in SOURCES}
    assert any(graph.values()), "the import pattern found nothing: it no longer matches the sources"
    assert (IDE / "js" / "teleop" / "dashboard.js").resolve() in graph[(IDE / "js" / "teleop" / "main.js").resolve()]
    state: dict[Path, str] = {}

    def visit(node: Path, path: list[Path]):
        state[node] = "open"
        for nxt in graph.get(node, []):
            if state.get(nxt) == "open":
                cycle = path[path.index(nxt):] + [nxt] if nxt in path else [node, nxt]
                raise AssertionError("import cycle: " + " -> ".join(str(p.relative_to(IDE)) for p in cycle))
            if nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = "done"

    for node in graph:
        if node not in state:
            visit(node, [node])


# What a module names relative to itself (resolved against the module's own URL, not the page's): static
# `import … from` / `export … from` / `import '…'`, `import('…')`, `new URL('…', import.meta.url)` (a Worker's
# script too, either side of a `?:`), and any other './' or '../' string (pyworker.js's FILES map, fetched
# with `new URL(url, import.meta.url)`). A fetch of 'api/…' or 'blocks/…' is the page's and not checked here.
STATIC = re.compile(r"""(?:^|\n)[ \t]*(?:import|export)\s[^;]*?\bfrom\s*['"]([^'"]+)['"]"""
                    r"""|(?:^|\n)[ \t]*import\s*['"]([^'"]+)['"]""")
DYNAMIC = re.compile(r"""\bimport\(\s*['"`]([^'"`]+)['"`]\s*\)""")
META_URL = re.compile(r"""new URL\(([^()]*?),\s*import\.meta\.url\s*\)""")
LITERAL = re.compile(r"""(['"`])(\.{1,2}/[^'"`\s]*)\1""")


def specifiers(path: Path) -> dict[str, list[str]]:
    text = path.read_text()
    found = {"static": [a or b for a, b in STATIC.findall(text)], "dynamic": DYNAMIC.findall(text),
             "url": [s for args in META_URL.findall(text) for _, s in LITERAL.findall(args)]}
    seen = {s for specs in found.values() for s in specs}
    found["other"] = [s for _, s in LITERAL.findall(text) if s not in seen]
    return {kind: [s for s in specs if s.startswith(("./", "../"))] for kind, specs in found.items()}


def test_every_import_names_a_file():
    """A path the browser would 404 on is caught here, before any page is opened (a module missing from a
    page's graph leaves the page unstarted, and a worker's only in the run that starts it)."""
    counts = {"static": 0, "dynamic": 0, "url": 0, "other": 0}
    missing = []
    for path in SOURCES:
        for kind, specs in specifiers(path).items():
            counts[kind] += len(specs)
            for spec in specs:
                target = re.split(r"[?#]", spec)[0]
                if "${" in target:   # a template: its fixed parts must match something (vendor/pyodide/<version>/)
                    base = path.parent
                    rel = re.sub(r"\$\{[^}]*\}", "*", target)
                    while rel.startswith("../"):
                        base, rel = base.parent, rel[3:]
                    hits = list(base.glob(rel.removeprefix("./").rstrip("/"))) if rel.strip("./") else [base]
                    ok = bool(hits) and all(IDE in h.resolve().parents for h in hits)
                else:
                    resolved = (path.parent / target).resolve()
                    inside = resolved == IDE or IDE in resolved.parents
                    ok = inside and (resolved.is_dir() if target.endswith("/") else resolved.is_file())
                if not ok:
                    missing.append(f"{path.relative_to(IDE)}: {kind} {spec!r}")
    # each pattern still matches the sources (a pattern that matches nothing would pass any tree)
    assert counts["static"] > 150 and counts["dynamic"] >= 5 and counts["url"] >= 4 and counts["other"] >= 4, counts
    assert (IDE / "vendor" / "roslib.mjs").is_file(), "the IDE is not built (make ide): vendor/ paths cannot be checked"
    assert not missing, "relative specifiers naming no file:\n" + "\n".join(missing)


def test_folders_stay_small():
    """ide/js in folders by page and by service (ide/README.md): none holds over 20 modules."""
    big = {str(d.relative_to(IDE)): n for d in [IDE / "js", *(p for p in (IDE / "js").rglob("*") if p.is_dir())]
           if (n := len(list(d.glob("*.js")))) > 20}
    assert not big, f"folders of ide/js over 20 modules: {big}"


PAGE_GLOBAL = re.compile(r"\b(?:window|globalThis|self)\.([A-Za-z_$][\w$]*)\s*=(?!=)")


def test_no_page_global():
    """No module puts its state on the page's global object: each page's entry exports it, and the
    tests read it through tests/support/page_state.js. (A worker's message handler is its own.)"""
    found = [f"{path.relative_to(IDE)}:{n}: {m.group(0)}" for path in SOURCES if (IDE / "js") in path.parents
             for n, line in enumerate(path.read_text().splitlines(), 1)
             for m in PAGE_GLOBAL.finditer(line) if m.group(1) != "onmessage"]
    assert not found, "globals set by the pages' modules:\n" + "\n".join(found)
    # the pattern still finds what it looks for
    assert PAGE_GLOBAL.search("window.rosgateIde = ide;") and not PAGE_GLOBAL.search("if (window.x === 1)")

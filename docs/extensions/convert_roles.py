"""Rewrite the Sphinx roles in the package's docstrings (``:func:``, ``:class:``, ``:meth:``, ``:mod:``, ``:data:``,
``:attr:``, ``:exc:``) as mkdocstrings cross-references, which the API pages render as links.

A role whose target the site renders becomes ``[`shown`][full.path]`` (autorefs resolves it; an unresolved one
fails ``mkdocs build --strict``); a role whose target exists but has no page (a private helper, an internal module)
becomes the code span ``` `shown` ```. ``~`` shows the last part of the path, as in Sphinx. Targets are resolved as
griffe sees the module: the enclosing class (for a method or attribute), the module's own and imported names, a path
relative to the package (``.power``), or an absolute path; a target that resolves nowhere is reported and left
alone (fix it by hand).

Usage, from the repository root, after ``mkdocs build --site-dir SITE`` (the rendered identifiers are read from it)::

    PYTHONPATH=. python docs/extensions/convert_roles.py SITE [--dry-run]

Only docstrings change (comments keep their text); the script is idempotent.
"""

from __future__ import annotations

import builtins
import importlib
import re
import sys
from collections import Counter
from pathlib import Path

import griffe

ROLE = re.compile(r":(?:py:)?(func|class|meth|mod|data|attr|exc|obj):`(?P<target>[^`\n]+)`")
PACKAGE = "packetloss_cvx"


def rendered_ids(site: Path) -> set[str]:
    """The identifiers the API pages anchor (mkdocstrings' heading ids)."""
    ids: set[str] = set()
    for page in (site / "api").rglob("*.html"):
        ids |= set(re.findall(rf'id="({PACKAGE}[\w.]*)"', page.read_text(encoding="utf-8")))
    return ids


def lookup(pkg: griffe.Module, path: str):
    """The griffe object at ``path`` (aliases followed), or None."""
    if path == PACKAGE:
        return pkg
    if not path.startswith(PACKAGE + "."):
        return None
    try:
        obj = pkg[path.removeprefix(PACKAGE + ".")]
        return obj.final_target if obj.is_alias else obj
    except (KeyError, griffe.AliasResolutionError, griffe.CyclicAliasError, ValueError):
        return None


def scope_of(obj):
    """The objects whose names a docstring of ``obj`` sees, innermost first."""
    chain = []
    while obj is not None:
        if obj.is_class or obj.is_module:
            chain.append(obj)
        obj = obj.parent
    return chain


def by_name(pkg: griffe.Module) -> dict[str, list[str]]:
    """Each name defined in the package -> the paths of the objects so named (the last resort of :func:`resolve`)."""
    names: dict[str, list[str]] = {}
    for obj in docstring_objects(pkg):
        names.setdefault(obj.name, []).append(obj.path)
    return names


def exists_at_run_time(owner, target: str) -> bool:
    """Whether ``target`` names something outside griffe's view: a builtin, another library's object, a name bound
    by tuple assignment in the owner's module (shown as a code span, never linked)."""
    head, _, rest = target.partition(".")
    module = importlib.import_module(owner.module.path)
    candidates = [getattr(module, head, None), getattr(builtins, head, None)]
    try:
        candidates.append(importlib.import_module(head))
    except ImportError:
        pass
    for value in candidates:
        for part in filter(None, rest.split(".")):
            value = getattr(value, part, None)
        if value is not None:
            return True
    return False


def resolve(pkg: griffe.Module, owner, target: str, names: dict[str, list[str]] | None = None) -> str | None:
    """The canonical path of ``target`` as written in a docstring of ``owner``, or None."""
    target = target.lstrip("~!").removesuffix("()")
    candidates: list[str] = []
    if target.startswith("."):
        module = owner.module
        base = module.path if module.is_init_module else module.parent.path
        dots = len(target) - len(target.lstrip("."))
        for _ in range(dots - 1):
            base = base.rpartition(".")[0]
        candidates.append(f"{base}.{target.lstrip('.')}")
    elif target.startswith(PACKAGE):
        candidates.append(target)
    else:
        head, _, rest = target.partition(".")
        for scope in scope_of(owner):
            if head in scope.members:
                member = scope.members[head]
                base = member.target_path if member.is_alias else member.path
                candidates.append(f"{base}.{rest}" if rest else base)
        candidates.append(f"{PACKAGE}.{target}")
    if names is not None and not target.startswith("."):
        head, _, rest = target.partition(".")
        if len(names.get(head, [])) == 1:
            candidates.append(f"{names[head][0]}.{rest}" if rest else names[head][0])
    for path in candidates:
        found = lookup(pkg, path)
        if found is not None:
            return found.path if not found.is_alias else found.target_path
    return None


def docstring_objects(obj):
    """Every object under ``obj`` (itself included) that carries its own docstring."""
    yield obj
    for member in obj.members.values():
        if member.is_alias:
            continue
        yield from docstring_objects(member)


def convert(pkg: griffe.Module, ids: set[str], dry_run: bool = False) -> Counter:
    tally: Counter = Counter()
    names = by_name(pkg)
    edits: dict[Path, list[tuple[int, int, object]]] = {}
    for obj in docstring_objects(pkg):
        if obj.docstring is None or obj.docstring.lineno is None:
            continue
        edits.setdefault(Path(obj.filepath), []).append((obj.docstring.lineno, obj.docstring.endlineno, obj))
    for path, spans in sorted(edits.items()):
        lines = path.read_text(encoding="utf-8").split("\n")
        changed = False
        for first, last, owner in spans:
            for i in range(first - 1, last):
                def replace(match: re.Match, owner=owner, where=f"{path}:{i + 1}") -> str:
                    written = match["target"]
                    titled = re.fullmatch(r"(?P<title>.+?)\s*<(?P<target>[^>]+)>", written)   # :role:`title <target>`
                    if titled:
                        shown, written = titled["title"], titled["target"]
                    else:
                        shown = written.lstrip("!")
                        shown = shown.lstrip("~").rpartition(".")[2] if shown.startswith("~") else shown
                    resolved = resolve(pkg, owner, written, names)
                    if resolved is None and exists_at_run_time(owner, written.lstrip("~!").removesuffix("()")):
                        tally["code"] += 1
                        tally["outside the package"] += 1
                        print(f"{where}: {match[0]} is outside the package: a code span", file=sys.stderr)
                        return f"`{shown}`"
                    if resolved is None:
                        tally["unresolved"] += 1
                        print(f"{where}: {match[0]} resolves nowhere", file=sys.stderr)
                        return match[0]
                    if resolved in ids:
                        tally["linked"] += 1
                        return f"[`{shown}`][{resolved}]"
                    tally["code"] += 1
                    return f"`{shown}`"
                new = ROLE.sub(replace, lines[i])
                if new != lines[i]:
                    lines[i] = new
                    changed = True
        if changed and not dry_run:
            path.write_text("\n".join(lines), encoding="utf-8")
            tally["files"] += 1
    return tally


def main(argv: list[str]) -> int:
    site = Path(argv[0])
    pkg = griffe.load(PACKAGE, search_paths=["."], resolve_aliases=False)
    tally = convert(pkg, rendered_ids(site), dry_run="--dry-run" in argv)
    print(dict(tally))
    return 1 if tally["unresolved"] else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

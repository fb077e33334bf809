"""No module reads another object's private attributes (the developer guide's rule).

An AST walk over ``rover_env/``: an attribute ``X._name`` is allowed only when ``X`` is
``self``, ``cls`` or ``super()`` (the object's own state); ``from m import _name`` is refused
everywhere (a module-private name belongs to its module). Dunder names are public protocol.
What a third-party library names with an underscore yet documents as its API is listed in
:data:`ALLOWED` with the reason.
"""

from __future__ import annotations

import ast
from pathlib import Path

import rover_env

PKG = Path(rover_env.__file__).parent

ALLOWED: dict[tuple[str, str], str] = {
    # MuJoCo's Python bindings document ``MjModel._address``/``MjData._address`` as the
    # pointer to hand to C code (the compiled sample loop takes mjModel*/mjData*).
    ("envs/fast_step.py", "_address"): "MuJoCo API",
    # ``os._exit`` is the standard library's documented exit without cleanup (a worker).
    ("executor.py", "_exit"): "standard library API",
}


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _own(node: ast.expr) -> bool:
    """``self``, ``cls`` or ``super()``: the object reading its own attributes."""
    if isinstance(node, ast.Name):
        return node.id in ("self", "cls")
    return (
        isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "super"
    )


def private_reads(root: Path = PKG) -> list[tuple[str, int, str]]:
    """(file relative to ``root``, line, expression) of every cross-object private access."""
    out = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Attribute) and _private(node.attr) and not _own(node.value):
                name, text = node.attr, ast.unparse(node)
            elif isinstance(node, ast.ImportFrom):
                names = [a.name for a in node.names if _private(a.name)]
                if not names:
                    continue
                name, text = names[0], f"from {node.module} import {', '.join(names)}"
            else:
                continue
            if (rel, name) not in ALLOWED:
                out.append((rel, node.lineno, text))
    return out


def test_no_module_reads_another_objects_private_attributes() -> None:
    bad = private_reads()
    assert not bad, "private attributes read across objects:\n" + "\n".join(
        f"  rover_env/{f}:{line}: {text}" for f, line, text in bad
    )


def test_the_walk_finds_what_it_must(tmp_path: Path) -> None:
    """The rule can fail: a private read, a private import and their allowed forms."""
    (tmp_path / "m.py").write_text(
        "from a import _hidden, shown\n"
        "class C:\n"
        "    def f(self, other):\n"
        "        self._x = other._y + super()._z() + other.__class__.__name__\n"
    )
    found = {text for _, _, text in private_reads(tmp_path)}
    assert found == {"from a import _hidden", "other._y"}


def test_every_allowance_is_still_needed() -> None:
    """An allow-list entry whose module no longer reads the name is removed (stays short)."""
    used: set[tuple[str, str]] = set()
    for rel, name in ALLOWED:
        tree = ast.parse((PKG / rel).read_text())
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and node.attr == name) or (
                isinstance(node, ast.ImportFrom) and any(a.name == name for a in node.names)
            ):
                used.add((rel, name))
    assert used == set(ALLOWED), f"unneeded allowances: {sorted(set(ALLOWED) - used)}"

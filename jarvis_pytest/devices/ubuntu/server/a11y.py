"""The accessibility tree from AT-SPI, bounded in nodes, depth and time; by default only what is on screen.

Every application on the session's accessibility bus is a child of the desktop node; below them, a node is kept
when it is showing (hidden menus and closed tabs are skipped with their subtrees unless `showing_only` is off).
Nodes are `{"role", "name", "box": [x, y, w, h], "states": [...], "text"?: ..., "children"?: [...]}`.

A node that manages its descendants (a LibreOffice Calc sheet: 2^31 - 1 cells, made on demand) is kept without
its children (`children_skipped`: how many it has), as screen readers do: walking them never ends. The deadline
is checked at every child, shown or not, so a walk ends in time however many children a node has.
"""

from __future__ import annotations

import threading
import time

MAX_TEXT = 200   # characters of a node's text kept
CALL_TIMEOUT_MS = (1000, 3000)  # one AT-SPI call to an application, to one that has just started (libatspi: 15 s)
_LOCK = threading.Lock()  # libatspi is not thread-safe: one walk at a time


def _atspi():
    import gi

    gi.require_version("Atspi", "2.0")
    from gi.repository import Atspi

    Atspi.set_timeout(*CALL_TIMEOUT_MS)  # an application that hangs costs a skipped subtree, not the walk
    return Atspi


def tree(max_nodes: int = 2000, max_depth: int = 30, timeout: float = 5.0, showing_only: bool = True) -> dict:
    """The desktop's accessible tree as nested dicts; `truncated` says whether a limit cut it short."""
    Atspi = _atspi()
    showing = Atspi.StateType.SHOWING
    deadline = time.monotonic() + timeout
    count = 0
    truncated = False

    def node(acc, depth: int) -> dict | None:
        nonlocal count, truncated
        if count >= max_nodes or time.monotonic() > deadline:
            truncated = True
            return None
        count += 1
        out: dict = {"role": acc.get_role_name(), "name": acc.get_name() or ""}
        states = acc.get_state_set()
        if states.contains(showing):
            ext = acc.get_extents(Atspi.CoordType.SCREEN)
            out["box"] = [ext.x, ext.y, ext.width, ext.height]
        out["states"] = sorted(s.value_nick for s in states.get_states())
        text = acc.get_text_iface()
        if text is not None:
            n = Atspi.Text.get_character_count(text)
            if n:
                out["text"] = Atspi.Text.get_text(text, 0, min(n, MAX_TEXT))
        n_children = acc.get_child_count()
        if depth >= max_depth:
            truncated = truncated or n_children > 0
            return out
        if n_children and states.contains(Atspi.StateType.MANAGES_DESCENDANTS):
            out["children_skipped"] = n_children
            return out
        children = []
        for i in range(n_children):
            if time.monotonic() > deadline:  # checked for hidden children too: a node may have millions
                truncated = True
                break
            try:
                child = acc.get_child_at_index(i)
                if child is None:
                    continue
                if showing_only and depth > 0 and not child.get_state_set().contains(showing):
                    continue
                sub = node(child, depth + 1)
            except Exception:  # an application that quit or does not answer: skip it, keep the rest
                continue
            if sub is None:
                break
            children.append(sub)
        if children:
            out["children"] = children
        return out

    with _LOCK:
        t0 = time.monotonic()
        root = node(Atspi.get_desktop(0), 0)
        elapsed = time.monotonic() - t0
    return {"tree": root, "nodes": count, "truncated": truncated, "elapsed_ms": round(elapsed * 1000, 1)}

"""The accessibility tree from AT-SPI, bounded in nodes, depth and time."""

from __future__ import annotations

import time


def tree(max_nodes: int = 2000, max_depth: int = 30, timeout: float = 5.0) -> dict:
    """The desktop's accessible tree as nested dicts (role, name, states, extents, children), truncated at the
    limits; `truncated` says whether a limit was hit."""
    import gi

    gi.require_version("Atspi", "2.0")
    from gi.repository import Atspi

    deadline = time.monotonic() + timeout
    count = 0
    truncated = False

    def node(acc, depth: int) -> dict | None:
        nonlocal count, truncated
        if count >= max_nodes or time.monotonic() > deadline:
            truncated = True
            return None
        count += 1
        out = {"role": acc.get_role_name(), "name": acc.get_name() or ""}
        try:
            ext = acc.get_extents(Atspi.CoordType.SCREEN)
            out["box"] = [ext.x, ext.y, ext.width, ext.height]
        except Exception:
            pass
        try:
            states = acc.get_state_set()
            out["states"] = [s.value_nick for s in Atspi.StateType.__enum_values__.values() if states.contains(s)]
        except Exception:
            pass
        if depth < max_depth:
            children = []
            for i in range(acc.get_child_count()):
                try:
                    child = acc.get_child_at_index(i)
                except Exception:
                    continue
                if child is None:
                    continue
                sub = node(child, depth + 1)
                if sub is None:
                    break
                children.append(sub)
            if children:
                out["children"] = children
        elif acc.get_child_count():
            truncated = True
        return out

    root = node(Atspi.get_desktop(0), 0)
    return {"tree": root, "nodes": count, "truncated": truncated}

"""`uiautomator dump` output → the accessibility tree in the node shape every device shares:
`{"role", "name", "box": [x, y, w, h], "states": [...], "text"?, "children"?}` (plus Android's `class` and,
when set, `id`), wrapped as `{"tree", "nodes", "truncated", "elapsed_ms"}`.

What the dump is (AOSP `cmds/uiautomator/.../DumpCommand.java` and `AccessibilityNodeInfoDumper.java`): an XML
document `<hierarchy rotation="r">` of nested `<node>` elements with the attributes index, text, resource-id,
class, package, content-desc, checkable, checked, clickable, enabled, focusable, focused, scrollable,
long-clickable, password, selected, bounds (`[x1,y1][x2,y2]`) and sometimes NAF; invisible children are not
dumped. When the UI never goes idle within 10 s the command prints `ERROR: could not get idle state.` (on
stderr, which `adb exec-out` merges into the stream), writes no file and still exits 0; with no active window it
prints `ERROR: null root node returned by UiTestAutomationBridge.`. `split_output` separates such messages
from the XML, and `parse` keeps whatever part of a cut-off document could be read (`truncated`).
"""

from __future__ import annotations

import re
import time
import xml.etree.ElementTree as ET

IDLE_ERROR = "ERROR: could not get idle state."
NULL_ROOT_ERROR = "ERROR: null root node returned by UiTestAutomationBridge."
MAX_NODES = 2000
MAX_DEPTH = 60
MAX_TEXT = 200
_BOUNDS = re.compile(r"^\[(-?\d+),(-?\d+)\]\[(-?\d+),(-?\d+)\]$")
_STATES = ("checkable", "checked", "clickable", "enabled", "focusable", "focused", "scrollable",
           "long-clickable", "password", "selected")
# class-name suffix → role (the AT-SPI role names the Ubuntu tree uses), first match wins
_ROLES: tuple[tuple[str, str], ...] = (
    ("EditText", "entry"), ("AutoCompleteTextView", "entry"), ("SearchAutoComplete", "entry"),
    ("CheckBox", "check box"), ("CheckedTextView", "check box"), ("RadioButton", "radio button"),
    ("Switch", "toggle button"), ("SwitchCompat", "toggle button"), ("SwitchMaterial", "toggle button"),
    ("ToggleButton", "toggle button"), ("CompoundButton", "toggle button"), ("ImageButton", "push button"),
    ("FloatingActionButton", "push button"), ("Button", "push button"), ("Chip", "push button"),
    ("TextView", "label"), ("ImageView", "image"), ("ProgressBar", "progress bar"), ("SeekBar", "slider"),
    ("RatingBar", "slider"), ("Slider", "slider"), ("Spinner", "combo box"), ("NumberPicker", "spin button"),
    ("RecyclerView", "list"), ("ListView", "list"), ("GridView", "list"), ("ScrollView", "scroll pane"),
    ("ViewPager", "scroll pane"), ("ViewPager2", "scroll pane"), ("WebView", "document web"),
    ("TabWidget", "page tab list"), ("TabLayout", "page tab list"), ("TabView", "page tab"),
    ("Toolbar", "tool bar"), ("ActionBar", "tool bar"), ("DatePicker", "date editor"),
    ("TimePicker", "panel"), ("VideoView", "video"), ("SurfaceView", "canvas"), ("TextureView", "canvas"),
    ("Layout", "panel"), ("ViewGroup", "panel"), ("View", "panel"), ("CardView", "panel"),
)


def split_output(text: str) -> tuple[str | None, list[str]]:
    """(the XML document or None, the `ERROR:` lines) of a dump's output, messages before or after it."""
    start = text.find("<?xml")
    if start < 0:
        start = text.find("<hierarchy")
    errors = [ln.strip() for ln in (text if start < 0 else text[:start]).splitlines()
              if ln.strip().startswith("ERROR")]
    if start < 0:
        return None, errors
    end = text.rfind("</hierarchy>")
    xml = text[start:end + len("</hierarchy>")] if end > start else text[start:]
    return xml, errors


def role_of(class_name: str) -> str:
    simple = class_name.rsplit(".", 1)[-1].rsplit("$", 1)[-1]
    for suffix, role in _ROLES:
        if simple.endswith(suffix):
            return role
    return "panel"


def box_of(bounds: str) -> list[int] | None:
    m = _BOUNDS.match(bounds or "")
    if not m:
        return None
    x1, y1, x2, y2 = (int(g) for g in m.groups())
    return [x1, y1, max(0, x2 - x1), max(0, y2 - y1)]


def _node(attrs: dict[str, str]) -> dict:
    cls = attrs.get("class", "")
    role = role_of(cls)
    editable = role == "entry"
    text = (attrs.get("text") or "")[:MAX_TEXT]
    desc = (attrs.get("content-desc") or "")[:MAX_TEXT]
    rid = attrs.get("resource-id") or ""
    short_id = rid.split(":id/", 1)[-1] if rid else ""
    hint = (attrs.get("hint") or "")[:MAX_TEXT]
    name = desc or (hint if editable else text) or short_id
    node: dict = {"role": role, "name": name}
    box = box_of(attrs.get("bounds", ""))
    if box is not None:
        node["box"] = box
    states = [s for s in _STATES if attrs.get(s) == "true"]
    if editable:
        states.append("editable")
    states.append("showing")  # uiautomator dumps visible nodes only
    node["states"] = states
    if text and (editable or text != name):
        node["text"] = text
    node["class"] = cls
    if rid:
        node["id"] = rid
    return node


def parse(xml: str, max_nodes: int = MAX_NODES, screen: tuple[int, int] | None = None) -> dict:
    """The dump as `{"tree", "nodes", "truncated", "elapsed_ms"}`; the root is the screen, its children the
    windows' top nodes. A document cut short yields what was read before the cut, with `truncated` set."""
    t0 = time.perf_counter()
    parser = ET.XMLPullParser(events=("start", "end"))
    root: dict = {"role": "screen", "name": "", "states": ["showing"]}
    if screen:
        root["box"] = [0, 0, screen[0], screen[1]]
    stack: list[dict] = []
    count = 0
    truncated = False
    skipped_depth = 0  # > 0 while inside a subtree that is cut (node or depth limit)

    def events():
        nonlocal truncated
        try:
            parser.feed(xml)
            parser.close()
        except ET.ParseError:
            truncated = True
        try:
            yield from parser.read_events()
        except ET.ParseError:
            truncated = True

    for event, elem in events():
        if elem.tag == "hierarchy":
            if event == "start" and "rotation" in elem.attrib:
                root["rotation"] = int(elem.attrib["rotation"]) if elem.attrib["rotation"].isdigit() else 0
            continue
        if elem.tag != "node":
            continue
        if event == "start":
            if skipped_depth or count >= max_nodes or len(stack) >= MAX_DEPTH:
                skipped_depth += 1
                truncated = True
                continue
            node = _node(dict(elem.attrib))
            count += 1
            parent = stack[-1] if stack else root
            parent.setdefault("children", []).append(node)
            stack.append(node)
        else:
            if skipped_depth:
                skipped_depth -= 1
            elif stack:
                stack.pop()
            elem.clear()
    if stack:  # elements left open: the document was cut off
        truncated = True
    return {"tree": root, "nodes": count, "truncated": truncated,
            "elapsed_ms": round((time.perf_counter() - t0) * 1000, 1)}


def parse_output(text: str, max_nodes: int = MAX_NODES, screen: tuple[int, int] | None = None
                 ) -> tuple[dict | None, list[str]]:
    """A dump's whole output (messages and XML) → (the tree or None when there is no XML, the ERROR lines)."""
    xml, errors = split_output(text)
    if xml is None:
        return None, errors
    return parse(xml, max_nodes=max_nodes, screen=screen), errors

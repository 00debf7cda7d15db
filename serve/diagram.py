"""The SVG diagram of a scene, drawn from what the SSP says: a box per component
(its name, its FMU's model and its ports on its bottom edge), a curve below the
boxes per glue joint between the two ports it ties (name, dofs, kind), and a
dashed arrow above them per causal connection.

The ports drawn are those the joints use (a component in no joint shows its FMU's
ports, by their conventional names ``P.f_x`` ...); a node set (``edge[1]``,
``edge[2]`` ...) is drawn as one port ``edge[]``.
"""
from __future__ import annotations

import math
import re
from xml.sax.saxutils import escape, quoteattr

WIDTH, GAP_X, GAP_Y, HEAD = 180, 90, 50, 44
NODE = re.compile(r"\[\d+\]$")


def _port_name(port: str) -> str:
    return NODE.sub("[]", port)


def _ports(scene: dict, models: dict) -> dict[str, list[str]]:
    """component -> its ports to draw: those its joints use, else (a component in no
    joint) at most six of its FMU's; sorted, node sets collapsed."""
    used = {c["path"]: set() for c in scene["components"]}
    for joint in scene["joints"]:
        for side in (joint["a"], joint["b"]):
            component, port = side.rsplit(".", 1)
            if component in used:
                used[component].add(_port_name(port))
    ports = {}
    for component in scene["components"]:
        names = used[component["path"]]
        if not names:
            model = models.get(component.get("model_id")) or {}
            names = sorted({_port_name(p) for p in model.get("ports", {})})[:6]
        ports[component["path"]] = sorted(names)
    return ports


def _text(x, y, text, size=12, weight="normal", anchor="middle", fill="#222") -> str:
    return (f'<text x="{x:.1f}" y="{y:.1f}" font-size="{size}" font-weight="{weight}" '
            f'text-anchor="{anchor}" fill="{fill}">{escape(text)}</text>')


def scene_svg(scene: dict, models: dict) -> str:
    """The diagram of a scene description (:func:`dsim.serve.inspect.describe_scene`);
    ``models``: model id -> its FMU description."""
    components = scene["components"]
    ports = _ports(scene, models)
    columns = max(1, min(len(components), 4))
    # ports sit on the bottom edge, so that a joint's curve runs below the boxes
    box_width = max([WIDTH] + [70 * len(names) + 30 for names in ports.values()])
    height = HEAD + 34
    rows = math.ceil(len(components) / columns)
    boxes, anchors, parts = {}, {}, []
    for k, component in enumerate(components):
        row, column = divmod(k, columns)
        x = 30 + column * (box_width + GAP_X)
        y = 30 + row * (height + GAP_Y + 40)
        path = component["path"]
        boxes[path] = (x, y, box_width, height)
        model = models.get(component.get("model_id")) or {}
        glued = path in scene.get("glued", ())
        parts.append(f'<g class="component" data-name={quoteattr(path)}>'
                     f'<rect x="{x}" y="{y}" width="{box_width}" height="{height}" rx="8" '
                     f'fill="{"#eef4ff" if glued else "#f4f4f4"}" stroke="#4a6fa5" '
                     'stroke-width="1.5"/>')
        parts.append(_text(x + box_width / 2, y + 20, path, 13, "bold"))
        parts.append(_text(x + box_width / 2, y + 36, model.get("modelName", component["fmu"]),
                           10, fill="#555"))
        names = ports[path]
        for i, port in enumerate(names):
            px, py = x + box_width * (i + 1) / (len(names) + 1), y + height
            anchors[(path, port)] = (px, py)
            parts.append(f'<circle cx="{px:.1f}" cy="{py}" r="4.5" fill="#4a6fa5"/>')
            parts.append(_text(px, py - 9, port, 11))
        parts.append("</g>")
    for k, joint in enumerate(scene["joints"]):
        ends = [anchors.get((side.rsplit(".", 1)[0], _port_name(side.rsplit(".", 1)[1])))
                for side in (joint["a"], joint["b"])]
        if None in ends:
            continue
        (ax, ay), (bx, by) = ends
        low = max(ay, by) + min(70.0, 25 + abs(bx - ax) / 6)
        color = "#c0392b" if joint["kind"] == "fixed" else "#27ae60"
        parts.append(f'<path class="joint" d="M{ax:.1f},{ay} C{ax:.1f},{low:.1f} '
                     f'{bx:.1f},{low:.1f} {bx:.1f},{by}" fill="none" stroke="{color}" '
                     f'stroke-width="2.5"/>')
        label = f'{joint["name"]} ({" ".join(joint["dofs"])}, {joint["kind"]})'
        # labels of neighbouring joints staggered, so that they do not cover each other
        parts.append(_text((ax + bx) / 2, 0.75 * low + 0.25 * max(ay, by) + 14 + 12 * (k % 3),
                           label, 11, fill=color))
    for k, connection in enumerate(scene["connections"]):
        start, end = (connection[key].split(".", 1)[0] for key in ("start", "end"))
        if start not in boxes or end not in boxes:
            continue
        sx, sy, sw, _ = boxes[start]
        ex, ey, ew, _ = boxes[end]
        offset = 12 * (k % 5) - 24
        x1, x2 = sx + sw / 2 + offset, ex + ew / 2 + offset
        high = min(sy, ey) - 24 - 6 * (k % 5)
        parts.append(f'<path class="connection" d="M{x1:.1f},{sy} C{x1:.1f},{high} '
                     f'{x2:.1f},{high} {x2:.1f},{ey}" fill="none" stroke="#8e44ad" '
                     'stroke-width="1.5" stroke-dasharray="5 3" marker-end="url(#arrow)"/>')
        parts.append(_text((x1 + x2) / 2, high + 4, f'{connection["start"]}'
                           f' → {connection["end"]}', 10, fill="#8e44ad"))
    width = 60 + columns * box_width + (columns - 1) * GAP_X
    total = 30 + rows * (height + GAP_Y + 40)
    return (f'<svg xmlns="http://www.w3.org/2000/svg" class="diagram" viewBox="0 -20 {width} '
            f'{total + 20}" width="{width}" height="{total + 20}" font-family="sans-serif" '
            f'role="img" aria-label={quoteattr("diagram of " + scene.get("name", ""))}>'
            '<defs><marker id="arrow" viewBox="0 0 10 10" refX="9" refY="5" markerWidth="7" '
            'markerHeight="7" orient="auto-start-reverse"><path d="M0,0 L10,5 L0,10 z" '
            'fill="#8e44ad"/></marker></defs>' + "".join(parts) + "</svg>")

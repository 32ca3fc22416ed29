"""The module graph from declared inputs and outputs, laid out as three columns.

Writers on the left, topics in the middle, readers on the right: every edge is a declaration
the board enforces (see ``ModuleBoard``), so the picture is what the code can do, not what a
diagram once said.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

from pydantic import BaseModel

from coffeebot.modules.base import Module

ROW_H = 30
BOX_H = 22
COLUMNS = {"writer": (10, 150), "topic": (260, 190), "reader": (560, 150)}


class Box(BaseModel):
    kind: Literal["writer", "topic", "reader"]
    label: str
    x: float
    y: float
    w: float
    h: float = BOX_H


class Edge(BaseModel):
    x1: float
    y1: float
    x2: float
    y2: float


class Graph(BaseModel):
    width: float
    height: float
    boxes: list[Box]
    edges: list[Edge]


def _column(kind: Literal["writer", "topic", "reader"], labels: list[str]) -> dict[str, Box]:
    x, w = COLUMNS[kind]
    return {
        label: Box(kind=kind, label=label, x=x, y=10 + i * ROW_H, w=w)
        for i, label in enumerate(labels)
    }


def module_graph(modules: Sequence[Module]) -> Graph:
    topics = sorted({t.name for m in modules for t in (*m.inputs, *m.outputs)})
    writers = _column("writer", [m.name for m in modules if m.outputs])
    readers = _column("reader", [m.name for m in modules if m.inputs])
    middle = _column("topic", topics)
    edges = []
    for m in modules:
        for t in m.outputs:
            a, b = writers[m.name], middle[t.name]
            edges.append(Edge(x1=a.x + a.w, y1=a.y + BOX_H / 2, x2=b.x, y2=b.y + BOX_H / 2))
        for t in m.inputs:
            a, b = middle[t.name], readers[m.name]
            edges.append(Edge(x1=a.x + a.w, y1=a.y + BOX_H / 2, x2=b.x, y2=b.y + BOX_H / 2))
    rows = max(len(writers), len(readers), len(middle), 1)
    boxes = [*writers.values(), *middle.values(), *readers.values()]
    return Graph(width=720, height=20 + rows * ROW_H, boxes=boxes, edges=edges)

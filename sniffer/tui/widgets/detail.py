"""Provides the detail pane: the selected frame's field tree, problems and a highlighting hex dump.

Tree nodes carry the byte span of their field (offsets in the body: unit byte and PDU);
moving over a node highlights those bytes in the hex dump, mapped to the raw frame
(for ASCII frames each body byte is two hex characters after the ':').
"""

from __future__ import annotations

from typing import ClassVar

from rich.style import Style
from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.widget import Widget
from textual.widgets import Static, Tree
from textual.widgets.tree import TreeNode

from dissectors.values import Field
from sniffer.meaning.describe import FrameDetail, register_span
from sniffer.outputs.listing import KIND_NAMES
from sniffer.text import plain
from sniffer.tui.render import (
    bytes_per_line,
    fit_words,
    hex_dump,
    latency_text,
    raw_span,
    register_label,
)
from sniffer.vocab import STATUS_NAMES, WARNING, Kind

Span = tuple[int, int]


class HexView(Widget):
    """A hex dump of one frame's raw bytes with one span highlighted."""

    COMPONENT_CLASSES: ClassVar[set[str]] = {
        "hex-view--highlight",
        "hex-view--offset",
        "hex-view--dim",
    }

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.raw = b""
        self.ascii = False
        self.highlight: Span | None = None  # body offsets
        self.body_at = 0  # where the body starts in raw (6 after a Modbus TCP header)

    def show(
        self, raw: bytes, ascii_mode: bool, highlight: Span | None = None, body_at: int = 0
    ) -> None:
        self.raw, self.ascii, self.highlight, self.body_at = raw, ascii_mode, highlight, body_at
        self.refresh(layout=True)

    def set_highlight(self, span: Span | None) -> None:
        if span != self.highlight:
            self.highlight = span
            self.refresh()

    def raw_highlight(self) -> Span | None:
        if self.highlight is None:
            return None
        start, end = raw_span(self.highlight, self.ascii)
        return start + self.body_at, end + self.body_at

    def render(self) -> Text:
        styles = {
            name: self.get_component_rich_style(f"hex-view--{name}", partial=True)
            for name in ("highlight", "offset", "dim")
        }
        per_line = bytes_per_line(self.size.width)
        return hex_dump(self.raw, self.raw_highlight(), per_line, styles)


class FieldTree(Tree[Span | None]):
    """The fields of a frame; a node's data is its byte span in the body."""

    COMPONENT_CLASSES: ClassVar[set[str]] = {
        "field-tree--problem",
        "field-tree--error",
        "field-tree--info",
        "field-tree--name",
        "field-tree--section",
    }

    def style(self, part: str) -> Style:
        return self.get_component_rich_style(f"field-tree--{part}", partial=True)


MBAP_BODY = 6  # a Modbus TCP frame's body (unit byte on) starts after 6 header bytes


class DetailPane(Vertical):
    """Title, field tree and hex dump of the selected frame."""

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.detail: FrameDetail | None = None
        self.partner_detail: FrameDetail | None = None
        self.where = ""  # a network row's connection, a gateway link (set by the app)

    def compose(self) -> ComposeResult:
        # the head wraps and scrolls: the title, the whole summary and every explanation,
        # never cut (the tree's lines are one line each)
        with VerticalScroll(id="detail-head"):
            yield Static(Text(""), id="detail-summary")  # first: the line people look for
            yield Static(Text("no frame selected"), id="detail-title")
        with Horizontal(id="detail-body"):
            tree: FieldTree = FieldTree(Text("frame"), id="fields")
            tree.show_root = False
            tree.guide_depth = 2
            yield tree
            yield HexView(id="hex")

    def show(self, d: FrameDetail | None, partner: FrameDetail | None = None) -> None:
        """Show a frame's details (`partner`: its paired request or answer, if any)."""
        self.detail, self.partner_detail = d, partner
        title = self.query_one("#detail-title", Static)
        summary = self.query_one("#detail-summary", Static)
        tree = self.query_one("#fields", FieldTree)
        hexview = self.query_one("#hex", HexView)
        tree.clear()
        if d is None:
            title.update(Text("no frame selected"))
            summary.update(Text(""))
            hexview.show(b"", False)
            return
        title.update(self._title(d, partner))
        summary.update(self._summary(d, tree))
        self.query_one("#detail-head", VerticalScroll).scroll_home(animate=False)
        self._fill(tree, d, partner)
        first = d.fields[0].span if d.fields else None
        hexview.show(d.view.raw, d.view.ascii, first, MBAP_BODY if d.view.mbap else 0)
        tree.cursor_line = 0 if d.fields else -1

    def _title(self, d: FrameDetail, partner: FrameDetail | None) -> Text:
        v = d.view
        text = Text()
        text.append(f"#{v.index} ", "bold")
        if v.kind in (Kind.NOISE, Kind.EVENT):
            text.append(plain(d.name) + " " + plain(d.summary, 200))
            return text
        text.append(f"{d.direction} u{v.unit} ")
        if d.label:
            text.append(plain(d.label, 60) + " ")
        text.append(f"fc {v.function}{' exception' if v.exception else ''} ")
        text.append(plain(d.name, 80))
        mode = "ascii" if v.ascii else "tcp" if v.mbap else "rtu"
        text.append(f"  {len(v.raw)} bytes {mode}, {KIND_NAMES[v.kind]}")
        if v.status and STATUS_NAMES[v.status] != KIND_NAMES[v.kind]:  # not 'exception' twice
            text.append(f", {STATUS_NAMES[v.status]}")
        latency = latency_text(d)
        if latency:
            text.append(f", {latency}")
        if partner is not None and "p:" not in self.where:
            role = "answer" if v.kind == Kind.REQUEST else "request"
            text.append(f"  (p: {role} #{partner.view.index})")
        if self.where:
            text.append("  " + plain(self.where, 120))
        return text

    def _summary(self, d: FrameDetail, tree: FieldTree) -> Text:
        """The whole summary, then every problem and explanation, one per line (wrapped)."""
        text = Text(plain(d.summary, 4000))
        for p in d.problems:
            part = "problem" if p.severity == WARNING else p.severity
            text.append("\n")
            text.append("! " + plain(p.text, 4000), tree.style(part))
        return text

    @staticmethod
    def _room(tree: FieldTree, depth: int) -> int:
        """Cells a label at `depth` has (less the guides and the scrollbar); a tree not
        yet laid out counts as 80 columns wide."""
        width = tree.size.width or 40
        return max(16, width - tree.guide_depth * (depth + 1) - 1)

    def _fill(self, tree: FieldTree, d: FrameDetail, partner: FrameDetail | None) -> None:
        # a label longer than its line ends with the last whole word and `…`: the whole
        # text is in the head above (summary and problems) and in the fields' values
        root = tree.root
        section = tree.style("section")
        for f in d.fields:  # raw words folded when the registers below name them
            self._field(root, f, tree, fold=bool(d.registers))
        if d.registers:
            node = root.add(Text(f"registers ({len(d.registers)})", section), expand=True)
            room = self._room(tree, 1)
            for r in d.registers:
                span = register_span(d.dissection, r)
                node.add_leaf(Text(register_label(r, room)), data=span)
        if d.problems:
            node = root.add(Text(f"problems ({len(d.problems)})", section), expand=True)
            room = self._room(tree, 1)
            for p in d.problems:  # coloured by severity; moving over one highlights its bytes
                part = "problem" if p.severity == WARNING else p.severity
                node.add_leaf(Text(fit_words(plain(p.text), room), tree.style(part)), data=p.span)
        if partner is not None:
            role = "answer" if d.view.kind == Kind.REQUEST else "request"
            head = f"{role} #{partner.view.index}: "
            line = Text(head, section)
            line.append(fit_words(plain(partner.summary, 4000), self._room(tree, 0) - len(head)))
            root.add_leaf(line)
        if not d.fields and not d.registers and not d.problems:
            root.add_leaf(Text(fit_words(plain(d.summary, 4000), self._room(tree, 0))))

    def _field(
        self,
        parent: TreeNode[Span | None],
        f: Field,
        tree: FieldTree,
        *,
        fold: bool = False,
        depth: int = 0,
    ) -> None:
        name = plain(f.name, 60)
        label = Text(name, tree.style("name"))
        label.append(": " + fit_words(plain(f.text, 4000), self._room(tree, depth) - len(name) - 2))
        if f.children:
            expand = len(f.children) <= (4 if fold else 16)
            node = parent.add(label, data=f.span, expand=expand)
            for child in f.children:
                self._field(node, child, tree, depth=depth + 1)
        else:
            parent.add_leaf(label, data=f.span)

    def on_resize(self) -> None:
        if self.detail is not None:  # the labels are fitted to the width
            self.show(self.detail, self.partner_detail)

    def on_tree_node_highlighted(self, event: Tree.NodeHighlighted[Span | None]) -> None:
        self.query_one("#hex", HexView).set_highlight(event.node.data)

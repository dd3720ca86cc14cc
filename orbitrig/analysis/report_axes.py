"""Axes of the report's figures: tick labels measured once per draw and once per tight box.

matplotlib's ``Axis.draw`` finds the ticks and measures every tick label's box, draws them, and
then places the axis label clear of the tick labels, for which it finds the ticks and measures
every box a second time, and finds the ticks a third time for the spine's extent (together
about a sixth of a report figure's drawing time); ``Axis.get_tightbbox`` (the room of a
figure's legend, plot_panels) likewise measures every box twice, for the label's place and for
its box. :class:`ReportAxes` draws with axes whose label placement takes the ticks and boxes
this draw (or this tight box) already found. Boxes are measured again, as matplotlib does, when
labels are aligned across axes (``Figure.align_labels``), whose siblings' boxes are needed. An
axes' tight box (constrained layout, a legend's room) finds each axis' ticks once more for each
of its four spines (their tick marks' length); ReportAxes' tight box finds them once in all. On an
Agg canvas (the PNG) an axis' tick marks of a side, each a line of one marker drawn on its own,
are drawn as one line of markers (one ``draw_markers`` call, the same pixels: each marker is placed
on its own pixel); vector formats keep matplotlib's tick by tick (their groups per tick).

Every look at an axes' view limits (hundreds per figure: each tick, spine, grid and transform)
first asks every axes sharing that axis whether it must be autoscaled; :class:`ReportAxes` keeps
the set of axes that asked to be autoscaled and skips the question while that set is empty.
That holds only where every axes sharing an axis with a ReportAxes is a ReportAxes (as in the
report's ``subplots``; a twin made by ``twinx`` would not be, and would not be asked).

Every line, collection and patch added to an axes is clipped to its frame (``Axes.patch``), whose
transform matplotlib builds anew for each (a fifth of ``ax.plot``'s time, and one more transform
for each to invalidate and compute when drawn); :class:`_Frame` keeps it while the frame stays.
"""

from __future__ import annotations

import weakref
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
from matplotlib import artist as martist
from matplotlib import axis as maxis
from matplotlib.backends.backend_agg import RendererAgg
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.axes import Axes


class _MeasuredOnce:
    """Axis mixin: during its draw or tight box, the ticks found and the tick-label boxes measured
    first are the ones the label's placement (and the spine's extent, the box) uses."""

    _drawing = False
    _drawn_ticks: Any = None
    _drawn_boxes: Any = None

    @martist.allow_rasterization
    def draw(self, renderer) -> None:
        """matplotlib's ``Axis.draw``, its ticks and tick-label boxes found once, its ticks drawn by
        :func:`_draw_ticks`."""
        if not self.get_visible():  # type: ignore[attr-defined]  # a mixin of maxis.Axis: mypy sees object
            return
        axis: Any = self
        with self.measuring():
            renderer.open_group(maxis.__name__, gid=axis.get_gid())
            ticks = axis._update_ticks()
            boxes1, boxes2 = axis._get_ticklabel_bboxes(ticks, renderer)
            _draw_ticks(ticks, renderer)
            axis._update_label_position(renderer)  # clear of the tick labels
            axis.label.draw(renderer)
            axis._update_offset_text_position(boxes1, boxes2)
            axis.offsetText.set_text(axis.major.formatter.get_offset())
            axis.offsetText.draw(renderer)
            renderer.close_group(maxis.__name__)
            axis.stale = False

    def get_tightbbox(self, renderer=None, *, for_layout_only=False):
        """matplotlib's box, its label placed by the ticks and boxes it measures (as in a draw)."""
        with self.measuring():
            return super().get_tightbbox(renderer, for_layout_only=for_layout_only)

    @contextmanager
    def measuring(self) -> Iterator[None]:
        """Ticks found and boxes measured once until the end (within an enclosing one: its)."""
        if self._drawing:
            yield
            return
        self._drawing, self._drawn_ticks, self._drawn_boxes = True, None, None
        try:
            yield
        finally:
            self._drawing, self._drawn_ticks, self._drawn_boxes = False, None, None

    def _update_ticks(self):
        if self._drawn_ticks is None:
            ticks = super()._update_ticks()
            if not self._drawing:
                return ticks
            self._drawn_ticks = ticks
        return self._drawn_ticks

    def _get_ticklabel_bboxes(self, ticks, renderer):
        if self._drawn_boxes is not None and ticks is self._drawn_ticks:  # measured for the label's place
            return self._drawn_boxes
        boxes = super()._get_ticklabel_bboxes(ticks, renderer)
        if self._drawing and ticks is self._drawn_ticks:
            self._drawn_boxes = boxes
        return boxes

    def _get_tick_boxes_siblings(self, renderer):
        if self._drawn_boxes is not None and self._alone():
            return self._drawn_boxes
        return super()._get_tick_boxes_siblings(renderer)

    def _alone(self) -> bool:
        """No other axes aligns its label with this one (``Figure.align_labels``)."""
        groups = self.axes.get_figure(root=False)._align_label_groups  # type: ignore[attr-defined]
        grouper = groups.get(self._get_axis_name())  # type: ignore[attr-defined]
        return grouper is None or len(grouper.get_siblings(self.axes)) <= 1  # type: ignore[attr-defined]


def _draw_ticks(ticks: list, renderer) -> None:
    """Each tick as ``Tick.draw`` draws it (grid line, tick marks, labels), except on an Agg canvas
    (the PNG) without grid lines: there the tick marks of one kind (``tick1line``, ``tick2line``)
    that look alike are drawn as one line of markers at every tick, one ``draw_markers`` call,
    each marker on the pixel matplotlib puts it on, before the labels (they do not overlap)."""
    shown = [t for t in ticks if t.get_visible()]
    if not isinstance(renderer, RendererAgg) or len(shown) < 2 or any(t.gridline.get_visible() for t in shown):
        for tick in ticks:
            tick.draw(renderer)
        return
    for lines in ([t.tick1line for t in shown], [t.tick2line for t in shown]):
        if not any(line.get_visible() for line in lines):  # a side without tick marks
            continue
        look = _look(lines[0])
        if not look[0] or any(_look(line) != look for line in lines[1:]):
            for line in lines:
                line.draw(renderer)
            continue
        first = lines[0]
        x0, y0 = first.get_xdata(orig=True), first.get_ydata(orig=True)
        first.set_data(
            *(np.concatenate([f(line, orig=True) for line in lines]) for f in (Line2D.get_xdata, Line2D.get_ydata))
        )
        try:
            first.draw(renderer)
        finally:
            first.set_data(x0, y0)
    for tick in shown:
        tick.label1.draw(renderer)
        tick.label2.draw(renderer)
    for tick in ticks:
        tick.stale = False


def _look(line: Line2D) -> tuple:
    """What a tick mark's drawing depends on besides its place (tick marks alike are drawn together)."""
    return (
        line.get_visible(),
        line.get_marker(),
        line.get_markersize(),
        line.get_markeredgewidth(),
        str(line.get_markeredgecolor()),
        str(line.get_markerfacecolor()),
        str(line.get_color()),
        line.get_alpha(),
        line.get_linestyle(),
        line.get_linewidth(),
        line.get_antialiased(),
        line.get_snap(),
        line.get_markevery(),
        line.get_drawstyle(),
        id(line.get_transform()),
        line.get_clip_on(),
        id(line.get_clip_box()),
        id(line.get_clip_path()),
        bool(line.get_path_effects()),
        line.get_sketch_params(),
        line.get_rasterized(),
        line.get_url(),
        line.get_gid(),
        line.get_agg_filter(),
        np.size(line.get_xdata(orig=True)),
    )


class _XAxis(_MeasuredOnce, maxis.XAxis):
    pass


class _YAxis(_MeasuredOnce, maxis.YAxis):
    pass


#: ReportAxes that asked to be autoscaled since they were last found not to need it
_STALE: weakref.WeakSet = weakref.WeakSet()


class ReportAxes(Axes):
    """Axes drawing their x and y axis with :class:`_MeasuredOnce` and skipping the autoscale
    question while no ReportAxes is stale (``fig.subplots(..., subplot_kw={"axes_class":
    ReportAxes})``); otherwise matplotlib's Axes."""

    def _request_autoscale_view(self, axis="all", tight=None) -> None:
        super()._request_autoscale_view(axis, tight)  # type: ignore[misc]  # private: not in the stubs
        _STALE.add(self)

    def _unstale_viewLim(self) -> None:
        if not _STALE:
            return
        super()._unstale_viewLim()  # type: ignore[misc]  # private: not in the stubs
        for ax in [ax for ax in _STALE if not any(ax._stale_viewlims.values())]:
            _STALE.discard(ax)

    def get_tightbbox(self, renderer=None, *args, **kwargs):
        """matplotlib's box, the ticks of each axis found once for it: for the axis' box and
        again for each of its spines' extents (their tick marks' length) matplotlib finds them."""
        with self.xaxis.measuring(), self.yaxis.measuring():
            return super().get_tightbbox(renderer, *args, **kwargs)

    def _gen_axes_patch(self) -> Rectangle:
        return _Frame((0.0, 0.0), 1.0, 1.0)

    def _init_axis(self) -> None:
        self.xaxis = _XAxis(self, clear=False)
        self.spines.bottom.register_axis(self.xaxis)
        self.spines.top.register_axis(self.xaxis)
        self.yaxis = _YAxis(self, clear=False)
        self.spines.left.register_axis(self.yaxis)
        self.spines.right.register_axis(self.yaxis)


class _Frame(Rectangle):
    """An axes' frame (``Axes.patch``, drawn and clipped to), its transform made once: the one it
    made last, while its corner, size, angle, rotation point and transform are the same."""

    _made: tuple | None = None

    def get_transform(self):
        key = (self._x0, self._y0, self._width, self._height, self.angle, self.rotation_point)
        outer = martist.Artist.get_transform(self)
        if self._made is None or self._made[0] != key or self._made[1] is not outer:
            self._made = key, outer, super().get_transform()
        return self._made[2]

"""The quantisation report: how far the fixed-point IK is from the float64 reference, next to float32.

``build_report`` computes the figures (:mod:`.quantisation`), draws the plots (:mod:`.plots`) and
writes ``DIR/report.json`` and ``DIR/index.html`` (:mod:`.html`). The page is a list of
:class:`~.html.Section` objects (title, HTML fragment, JSON dict), so later sections (e.g. the
HDL/C/model bit-accuracy table) are appended without touching the existing ones.
"""

from .build import build_report, quantisation_sections
from .html import Section, write_report
from .quantisation import figures
from .sampling import compute
from .summary import summary_text

__all__ = ["Section", "write_report", "compute", "figures", "summary_text", "build_report",
           "quantisation_sections"]

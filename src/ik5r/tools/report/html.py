"""The report page: an ordered list of sections, each (title, HTML fragment, JSON dict).

:func:`write_report` writes ``index.html`` (self-contained folder: images by relative file name)
and ``report.json`` = ``{"meta": ..., "sections": {key: {"title": ..., "data": ...}}}``. A new part
of the report (e.g. the HDL / C / model bit-accuracy table) is one more :class:`Section`.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Section:
    key: str                 # JSON key and HTML anchor
    title: str
    html: str                # fragment (already escaped)
    data: dict = field(default_factory=dict)
    images: tuple[str, ...] = ()  # PNG file names (relative) the fragment refers to


def esc(text) -> str:
    return html.escape(str(text))


def fmt(value, digits=3) -> str:
    if value is None:
        return "–"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return f"{int(value):,}"
    value = float(value)
    if not math.isfinite(value):
        return "–"
    if value == 0:
        return "0"
    return f"{value:.{digits}g}"


def table(header, rows, caption=None, first_col_header=True) -> str:
    """An HTML table; cells that are not str are formatted with :func:`fmt`."""
    def cell(v):
        return esc(v) if isinstance(v, str) else fmt(v)

    out = ["<table>"]
    if caption:
        out.append(f"<caption>{esc(caption)}</caption>")
    out.append("<tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr>")
    for row in rows:
        cells = [f"<th>{cell(row[0])}</th>" if first_col_header else f"<td>{cell(row[0])}</td>"]
        cells += [f"<td>{cell(v)}</td>" for v in row[1:]]
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def image(name: str, alt: str) -> str:
    return f'<figure><img src="{esc(name)}" alt="{esc(alt)}"><figcaption>{esc(alt)}</figcaption></figure>'


def para(text: str) -> str:
    return f"<p>{text}</p>"


_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1400px; margin: 1em auto; padding: 0 1em; color: #222; }
h1 { font-size: 1.5em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 2em; }
table { border-collapse: collapse; margin: .6em 0 1.2em; font-size: .9em; }
caption { text-align: left; font-weight: 600; padding: .3em 0; }
th, td { border: 1px solid #ccc; padding: .2em .6em; text-align: right; }
tr th:first-child { text-align: left; background: #f6f6f6; }
th { background: #eee; }
img { max-width: 100%; } figure { margin: 1em 0; } figcaption { font-size: .85em; color: #555; }
pre { background: #f6f6f6; padding: .6em; overflow-x: auto; }
.ok { color: #070; font-weight: 600; } .bad { color: #b00; font-weight: 600; }
nav ul { columns: 2; }
"""


def jsonable(value):
    """Numpy scalars/arrays to plain Python; non-finite floats to None."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    return value


def render_page(title: str, sections: list[Section], meta: dict | None = None) -> str:
    nav = "".join(f'<li><a href="#{esc(s.key)}">{esc(s.title)}</a></li>' for s in sections)
    body = "\n".join(f'<section id="{esc(s.key)}">\n<h2>{esc(s.title)}</h2>\n{s.html}\n</section>'
                     for s in sections)
    stamp = ""
    if meta:
        stamp = "<p>" + " · ".join(f"{esc(k)}: {esc(v)}" for k, v in meta.items()
                                   if not isinstance(v, dict)) + "</p>"
    return (f"<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{esc(title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n"
            f"<h1>{esc(title)}</h1>\n{stamp}\n<nav><ul>{nav}</ul></nav>\n{body}\n</body>\n</html>\n")


def write_report(out_dir, sections: list[Section], meta: dict, title: str = "ik5r report") -> dict:
    """Write ``index.html`` and ``report.json`` into ``out_dir``; returns the JSON document."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for s in sections:
        for name in s.images:
            if not (out_dir / name).is_file():
                raise FileNotFoundError(f"section {s.key!r} refers to missing image {name}")
    doc = jsonable({"meta": meta,
                    "sections": {s.key: {"title": s.title, "data": s.data} for s in sections}})
    (out_dir / "report.json").write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n")
    (out_dir / "index.html").write_text(render_page(title, sections, meta))
    return doc

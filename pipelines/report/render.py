"""The report's one HTML layer: jinja2 templates (autoescaped), tables, embedded figures, reading artifacts.

Values inserted into a template of ``templates/`` are escaped; only the templates' own markup and the
``Markup`` that :func:`render` returns pass through as HTML. The sections compute their numbers and call
:func:`render`; :func:`table` and :func:`figure` are the shared fragments.
"""

from __future__ import annotations

import base64
import io
import json
import math
from pathlib import Path
from typing import NamedTuple

import jinja2
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd  # noqa: E402
from markupsafe import Markup  # noqa: E402

#: Folder of the report's templates.
TEMPLATES = Path(__file__).resolve().parent / "templates"

#: What an undefined number (NaN, or null in a JSON artifact) prints as.
MISSING = "–"


def number(value, spec: str = ".4g", missing: str = MISSING) -> str:
    """``format(value, spec)``, or ``missing`` for None and NaN."""
    if value is None or (isinstance(value, (float, np.floating)) and math.isnan(value)):
        return missing
    return format(value, spec)


ENV = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), autoescape=True, undefined=jinja2.StrictUndefined,
                         trim_blocks=True, lstrip_blocks=True)
ENV.filters["f"] = number


def render(template: str, **context) -> Markup:
    """The HTML of ``templates/<template>`` with ``context`` (values escaped)."""
    return Markup(ENV.get_template(template).render(**context))


def _cell(value, fmt) -> str:
    if fmt is not None:
        return fmt(value)
    if value is None or isinstance(value, (float, np.floating)):
        return number(value)
    return str(value)


def table(df: pd.DataFrame, fmt: dict | None = None, left: tuple = ()) -> Markup:
    """A DataFrame as an HTML table: floats to 4 significant digits unless ``fmt[column]`` formats them.

    ``left`` names the columns aligned left (text); NaN and None print as :data:`MISSING`.
    """
    fmt = fmt or {}
    rows = [[(c, _cell(v, fmt.get(c))) for c, v in zip(df.columns, r)] for r in df.itertuples(index=False)]
    return render("table.html.j2", columns=[str(c) for c in df.columns], rows=rows, left=set(left))


def figure(fig, caption: str) -> Markup:
    """A matplotlib figure as an embedded PNG with its caption; the figure is closed."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight", metadata={"Software": None})
    plt.close(fig)
    return render("figure.html.j2", caption=caption, data=base64.b64encode(buf.getvalue()).decode("ascii"))


def read_artifact(path: Path):
    """A stored JSON or Parquet artifact, or None if it is not there."""
    path = Path(path)
    if not path.exists():
        return None
    if path.suffix == ".json":
        return json.loads(path.read_text())
    return pd.read_parquet(path)


class RunParts(NamedTuple):
    """A run folder as the report reads it: ``root``, less the parts (a folder or file name directly under it)
    :func:`scioc.pipelines.report.parts.check_run` leaves out, each with why."""

    root: Path
    left_out: dict = {}

    @classmethod
    def of(cls, run) -> "RunParts":
        """``run`` itself, or a folder read as it is (no part left out)."""
        return run if isinstance(run, RunParts) else cls(Path(run), {})

    def kept(self, rel: str) -> bool:
        return Path(rel).parts[0] not in self.left_out

    def read(self, rel: str):
        """:func:`read_artifact` of ``root / rel``; None where its part is left out."""
        return read_artifact(self.root / rel) if self.kept(rel) else None

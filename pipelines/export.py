"""A lab's export as data: the names and units of its columns, and the conversion to the data convention and back.

An experiment file's ``[columns]`` and ``[units]`` tables (:mod:`scioc.pipelines.experiment`) become an
:class:`ExportFormat`. A design that carries one is an :class:`ExportDesign`;
:func:`scioc.pipelines.io.load_study` reads the study files under its names and converts its units
before any plausibility check. The default format is the data convention itself, and a design
without ``[columns]`` and ``[units]`` stays a plain :class:`scioc.models.design.Design`, so its
experiment hash does not change.

- ``[columns]``: scioc's column name = the file's column name. ``from_file_name``: a regular expression
  matched against each file's name without its extension (the whole name must match); its named
  groups ``subject``, ``condition`` and ``trial`` give those columns for every row of the file, e.g.
  ``'(?P<subject>.+)'`` makes the file name the subject.
- ``[units]``: ``angle`` (angle, angle_ref) "rad" or "deg"; ``velocity`` "rad/s" or "deg/s"; ``torque``
  (u_A, u_H) "N*m", "N*cm" or "N*mm" (also written N·cm or Ncm); ``time`` (t) "s" or "ms".
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from scioc.models.design import Design

#: scioc's columns (the data convention), in the order of the ``[columns]`` table.
COLUMNS = ("subject", "condition", "trial", "t", "angle", "angle_ref", "u_A", "velocity", "u_H")
#: The columns ``[columns] from_file_name`` may take from a file's name.
FILE_NAME_GROUPS = ("subject", "condition", "trial")
#: Per quantity of ``[units]``: each unit as (mul, div), a value in it being ``x * mul / div`` in scioc's unit,
#: which comes first. Dividing by 100 or 1000 gives the correctly rounded value of an N·cm, N·mm or ms.
UNITS = {"angle": {"rad": (1.0, 1.0), "deg": (math.pi, 180.0)},
         "velocity": {"rad/s": (1.0, 1.0), "deg/s": (math.pi, 180.0)},
         "torque": {"N*m": (1.0, 1.0), "N*cm": (1.0, 100.0), "N*mm": (1.0, 1000.0)},
         "time": {"s": (1.0, 1.0), "ms": (1.0, 1000.0)}}
#: Other spellings of the torque units.
SPELLINGS = {f"N{sep}{u}": f"N*{u}" for sep in ("·", "") for u in ("m", "cm", "mm")}
#: The quantity of each numeric column.
QUANTITY = {"t": "time", "angle": "angle", "angle_ref": "angle", "velocity": "velocity", "u_A": "torque",
            "u_H": "torque"}


def canonical_unit(quantity: str, unit: str) -> str | None:
    """The canonical spelling of ``unit`` of ``quantity`` (a key of :data:`UNITS`), or None if it is not one."""
    unit = SPELLINGS.get(unit, unit)
    return unit if unit in UNITS[quantity] else None


@dataclass(frozen=True)
class ExportFormat:
    """How a lab's study files differ from the data convention (the module docstring); the default is none.

    ``columns``: (scioc's name, the file's name) per renamed column; ``units``: (quantity, unit) per
    quantity not in scioc's unit; ``from_file_name``: the pattern of the file names, or None. Entries
    equal to the convention are dropped and the rest put in canonical order, so equal formats compare equal.
    """

    columns: tuple[tuple[str, str], ...] = ()
    units: tuple[tuple[str, str], ...] = ()
    from_file_name: str | None = None

    def __post_init__(self):
        columns = dict(self.columns)
        if set(columns) - set(COLUMNS) or len({columns.get(c, c) for c in COLUMNS}) != len(COLUMNS):
            raise ValueError(f"ExportFormat.columns must map distinct file columns to {COLUMNS}; got {self.columns!r}")
        units = {}
        for quantity, unit in self.units:
            if quantity not in UNITS or canonical_unit(quantity, unit) is None:
                raise ValueError(f"ExportFormat.units: {quantity!r} = {unit!r} is not a unit of {tuple(UNITS)}")
            units[quantity] = canonical_unit(quantity, unit)
        own = {q: next(iter(table)) for q, table in UNITS.items()}  # scioc's unit of each quantity
        object.__setattr__(self, "columns", tuple((c, columns[c]) for c in COLUMNS if columns.get(c, c) != c))
        object.__setattr__(self, "units", tuple((q, units[q]) for q in UNITS if units.get(q, own[q]) != own[q]))
        if self.from_file_name is not None:
            groups = set(re.compile(self.from_file_name).groupindex)
            if not groups or groups - set(FILE_NAME_GROUPS) or groups & set(columns):
                raise ValueError(f"ExportFormat.from_file_name needs named groups among {FILE_NAME_GROUPS}, none of "
                                 f"them renamed; got {self.from_file_name!r}")

    @property
    def is_convention(self) -> bool:
        """Whether the files are in scioc's own names and units."""
        return not self.columns and not self.units and self.from_file_name is None

    @property
    def file_columns(self) -> tuple[str, ...]:
        """The columns :attr:`from_file_name` takes from file names."""
        return () if self.from_file_name is None else tuple(re.compile(self.from_file_name).groupindex)

    def name(self, column: str) -> str:
        """The file's name of scioc's ``column``."""
        return dict(self.columns).get(column, column)

    def unit(self, column: str) -> str:
        """The unit of scioc's numeric ``column`` in the file."""
        quantity = QUANTITY[column]
        return dict(self.units).get(quantity, next(iter(UNITS[quantity])))

    def converts(self, column: str) -> bool:
        """Whether ``column`` is in the file in another unit than scioc's."""
        return column in QUANTITY and QUANTITY[column] in dict(self.units)

    def to_scioc(self, column: str, values: np.ndarray) -> np.ndarray:
        """``values`` of ``column`` in the file's unit, in scioc's (rad, rad/s, N·m, s)."""
        mul, div = UNITS[QUANTITY[column]][self.unit(column)]
        return values * mul / div if self.converts(column) else values

    def from_scioc(self, column: str, values: np.ndarray) -> np.ndarray:
        """``values`` of ``column`` in scioc's unit, in the file's: the inverse of :meth:`to_scioc`."""
        mul, div = UNITS[QUANTITY[column]][self.unit(column)]
        return values * div / mul if self.converts(column) else values

    def file_labels(self, stem: str) -> dict | None:
        """The columns :attr:`from_file_name` takes from a file name without extension; None if it does not match."""
        if self.from_file_name is None:
            return {}
        match = re.fullmatch(self.from_file_name, stem)
        return None if match is None else {k: v for k, v in match.groupdict().items() if v is not None}


#: The data convention: scioc's own names and units.
CONVENTION = ExportFormat()


@dataclass(frozen=True)
class ExportDesign(Design):
    """A :class:`scioc.models.design.Design` whose study files are a lab's export in the format ``export``."""

    export: ExportFormat = CONVENTION


def export_of(design: Design) -> ExportFormat:
    """The format ``design``'s study files are in (:data:`CONVENTION` for a plain Design)."""
    return design.export if isinstance(design, ExportDesign) else CONVENTION


def convention(design: Design) -> Design:
    """``design`` without its export format: the experiment of the same study in the data convention."""
    return Design(**{f.name: getattr(design, f.name) for f in fields(Design)})


def with_export(design: Design, export: ExportFormat) -> Design:
    """``design`` with study files in ``export``; a plain Design when that is the convention."""
    own = {f.name: getattr(design, f.name) for f in fields(Design)}
    return Design(**own) if export.is_convention else ExportDesign(**own, export=export)


def to_export(table: pd.DataFrame, export: ExportFormat) -> pd.DataFrame:
    """``table``, in the data convention, in ``export``'s names and units: what :func:`scioc.pipelines.io.load_study`
    reads back.

    The columns :attr:`ExportFormat.from_file_name` takes from file names are dropped; they belong in the names
    of the files the caller writes.
    """
    out = {}
    for column in table.columns:
        if column in export.file_columns:
            continue
        values = table[column]
        if export.converts(column):
            values = pd.Series(export.from_scioc(column, values.to_numpy(dtype=float)), index=table.index)
        out[export.name(column)] = values
    return pd.DataFrame(out)

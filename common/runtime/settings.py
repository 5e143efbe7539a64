"""Declare a setting once; its README table and ``--help`` text come from that declaration.

:func:`setting` is a pydantic ``Field`` that also carries the setting's unit and whether it is
``advanced`` (for tuning; an integrator sets the others). :func:`setting_rows` walks a settings
model, nested sections included, and gives one :class:`SettingRow` per leaf: its dotted name,
type, default, range (from the field's own constraints), unit and description.
:func:`markdown_table` renders the rows for a README (the integrator's table, then the advanced
one), :func:`settings_epilog` for ``--help`` and :func:`flag_help` for a flag that sets one of them.
"""

from __future__ import annotations

import argparse
import enum
import textwrap
import types
from dataclasses import dataclass
from pathlib import PurePath
from typing import Annotated, Any, Iterator, Literal, Union, get_args, get_origin

from pydantic import BaseModel, Field, model_validator
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

__all__ = ["AdvancedBlock", "SettingRow", "add_settings_epilog", "find_row", "flag_help", "markdown_table", "select_rows", "setting",
           "setting_rows", "settings_epilog", "unfold_advanced"]


def setting(default: Any = PydanticUndefined, description: str = "", *, unit: str | None = None,
            ge: float | None = None, gt: float | None = None, le: float | None = None, lt: float | None = None,
            advanced: bool = False, default_text: str | None = None, **field_kwargs: Any) -> Any:
    """A settings field: ``default`` (``...`` or none with ``default_factory=``: required), what it does,
    its ``unit`` (``m``, ``s``, ``Hz``, ``px``...) and bounds; ``advanced`` for one that only tuning
    needs. ``default_text`` is how to show a default computed at start-up (e.g. from the environment).
    Other keywords go to ``pydantic.Field`` as they are (``multiple_of``, ``min_length``, ``pattern``...)."""
    if not description.strip():
        raise TypeError("setting() needs a description: say what the setting does")
    extra: dict[str, Any] = {}
    if unit:
        extra["unit"] = unit
    if advanced:
        extra["advanced"] = True
    if default_text is not None:
        extra["default_text"] = default_text
    if "default_factory" not in field_kwargs:
        field_kwargs["default"] = default
    return Field(description=description, ge=ge, gt=gt, le=le, lt=lt, json_schema_extra=extra or None,
                 **field_kwargs)


class AdvancedBlock(BaseModel):
    """A settings section whose advanced settings are written under its ``advanced:`` key, apart
    from the ones an integrator sets (``robust: {gate_sq: 13.8, advanced: {q_accel: 3.0}}``);
    written beside the others they are taken too, as before. Only advanced settings go under
    ``advanced:``; one given both ways is refused, naming it."""

    @model_validator(mode="before")
    @classmethod
    def _unfold_advanced(cls, data: Any) -> Any:
        return _lift(cls, data)


def _lift(model: type[BaseModel], data: Any) -> Any:
    """``data`` of section ``model`` with its ``advanced:`` block lifted beside the others
    (ValueError: a setting there that is not advanced, or given both ways)."""
    if not isinstance(data, dict) or "advanced" not in data or "advanced" in model.model_fields:
        return data
    block = data["advanced"] if data["advanced"] is not None else {}
    if not isinstance(block, dict):
        raise ValueError(f"advanced: must be a mapping of advanced settings, got {block!r}")
    allowed = {f.alias or n for n, f in model.model_fields.items() if _extra(f).get("advanced")}
    wrong = sorted(set(block) - allowed)
    if wrong:
        known = {f.alias or n for n, f in model.model_fields.items()}
        why = [f"{k} (not advanced: write it beside advanced:)" if k in known else f"{k} (no such setting)"
               for k in wrong]
        raise ValueError(f"advanced: {', '.join(why)}; advanced settings here: {', '.join(sorted(allowed)) or 'none'}")
    both = sorted(set(block) & set(data))
    if both:
        raise ValueError(f"{', '.join(both)} given both under advanced: and beside it: keep one")
    return {**{k: v for k, v in data.items() if k != "advanced"}, **block}


def unfold_advanced(model: type[BaseModel], data: Any, where: str = "") -> Any:
    """``data`` (one layer of settings for ``model``: a file, the environment, the flags) with
    every section's ``advanced:`` block lifted beside that section's other settings, so that layers
    that write a setting in the two ways merge as one; ValueError naming the section."""
    if not isinstance(data, dict):
        return data
    if issubclass(model, AdvancedBlock):
        try:
            data = _lift(model, data)
        except ValueError as exc:
            raise ValueError(f"{where or 'settings'}: {exc}") from exc
    out = dict(data)
    for name, field in model.model_fields.items():
        key = field.alias or name
        sub = _section(_strip_none(field.annotation)[0])
        if sub is not None and isinstance(out.get(key), dict):
            out[key] = unfold_advanced(sub, out[key], f"{where}.{key}" if where else key)
    return out


@dataclass(frozen=True)
class SettingRow:
    """One leaf setting, its text as the README and ``--help`` show it; ``written``: its dotted
    path as a settings file writes it (an advanced one under its section's ``advanced:``)."""

    name: str  #: dotted, e.g. ``depth.min_height_m``
    type: str  #: e.g. ``number``, ``integer``, ``text``, ``list of text``
    default: str  #: ``required`` when it has none
    range: str  #: e.g. ``[0.25, 8]``, ``> 0``, ``hog, depth``; "" when anything of its type goes
    unit: str
    description: str
    advanced: bool
    written: str = ""


def _extra(field: FieldInfo) -> dict[str, Any]:
    extra = field.json_schema_extra
    return extra if isinstance(extra, dict) else {}


def _strip_none(annotation: Any) -> tuple[Any, bool]:
    """``annotation`` without its ``None`` member, and whether it had one."""
    if get_origin(annotation) in (Union, types.UnionType):
        members = [a for a in get_args(annotation) if a is not type(None)]
        if len(members) < len(get_args(annotation)):
            return (members[0] if len(members) == 1 else Union[tuple(members)]), True
    return annotation, False


def _section(annotation: Any) -> type[BaseModel] | None:
    return annotation if isinstance(annotation, type) and issubclass(annotation, BaseModel) else None


def _value(value: Any) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, enum.Enum):
        return _value(value.value)
    if isinstance(value, float):
        text = f"{value:g}"
        return text if any(c in text for c in ".eni") else f"{text}.0"
    if isinstance(value, str):
        return value if value else '""'
    if isinstance(value, PurePath):
        return str(value)
    if isinstance(value, BaseModel):
        return _value(value.model_dump(by_alias=True))
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    return str(value)


def _num(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _bounds(metadata: list[Any]) -> str:
    """The range a field's constraints allow, e.g. ``[0, 1]``, ``(1, 2]``, ``≥ 1``, ``multiple of 8``."""
    got: dict[str, Any] = {}
    for item in metadata:
        for key in ("ge", "gt", "le", "lt", "multiple_of", "min_length", "max_length", "pattern"):
            if getattr(item, key, None) is not None:
                got[key] = getattr(item, key)
    low = ("[", got["ge"]) if "ge" in got else ("(", got["gt"]) if "gt" in got else None
    high = (got["le"], "]") if "le" in got else (got["lt"], ")") if "lt" in got else None
    parts = []
    if low and high:
        parts.append(f"{low[0]}{_num(low[1])}, {_num(high[0])}{high[1]}")
    elif low:
        parts.append(f"{'≥' if low[0] == '[' else '>'} {_num(low[1])}")
    elif high:
        parts.append(f"{'≤' if high[1] == ']' else '<'} {_num(high[0])}")
    if "multiple_of" in got:
        parts.append(f"multiple of {_num(got['multiple_of'])}")
    if got.get("min_length") == 1 and "max_length" not in got:
        parts.append("not empty")
    elif "min_length" in got or "max_length" in got:
        parts.append(f"length {got.get('min_length', 0)} to {got.get('max_length', '∞')}")
    if "pattern" in got:
        parts.append(f"matching {got['pattern']}")
    return ", ".join(parts)


def _type(annotation: Any) -> str:
    """A type in words: ``number``, ``integer``, ``list of text``, ``(integer, integer)``..."""
    annotation, optional = _strip_none(annotation)
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Annotated:
        inner = args[0]
        metadata = [m for a in args[1:] for m in (a.metadata if isinstance(a, FieldInfo) else [a])]
        bounds = _bounds(metadata)
        text = f"{_type(inner)} {bounds}" if bounds else _type(inner)
    elif origin is Literal:
        text = "one of " + ", ".join(_value(a) for a in args)
    elif origin in (list, set, frozenset):
        text = f"list of {_type(args[0])}" if args else "list"
    elif origin is tuple:
        text = "(" + ", ".join(_type(a) for a in args if a is not Ellipsis) + (", ...)" if Ellipsis in args else ")")
    elif origin is dict:
        text = f"map of {_type(args[0])} to {_type(args[1])}" if args else "map"
    elif origin in (Union, types.UnionType):
        text = " or ".join(_type(a) for a in args)
    elif (section := _section(annotation)) is not None:
        text = "{" + ", ".join(f.alias or n for n, f in section.model_fields.items()) + "}"
    else:
        text = {bool: "true/false", int: "integer", float: "number", str: "text"}.get(annotation, "")
        if not text and isinstance(annotation, type) and issubclass(annotation, PurePath):
            text = "path"
        text = text or getattr(annotation, "__name__", str(annotation))
    return f"{text} or none" if optional else text


def _default(field: FieldInfo) -> str:
    extra = _extra(field)
    if "default_text" in extra:
        return str(extra["default_text"])
    if field.is_required():
        return "required"
    return _value(field.get_default(call_default_factory=True))


def setting_rows(model: type[BaseModel], prefix: str = "") -> Iterator[SettingRow]:
    """One row per leaf setting of ``model``, in declaration order, a nested section's rows under
    its dotted name. An optional section (``X | None``) is a row of its own, then its settings'."""
    for name, field in model.model_fields.items():
        key = f"{prefix}{field.alias or name}"
        annotation, optional = _strip_none(field.annotation)
        section = _section(annotation)
        if section is not None and not optional:
            yield from setting_rows(section, f"{key}.")
            continue
        extra = _extra(field)
        literal = get_origin(annotation) is Literal
        bounds = ", ".join(_value(a) for a in get_args(annotation)) if literal else _bounds(field.metadata)
        if bounds and optional:
            bounds += " or none"
        advanced = bool(extra.get("advanced", False))
        written = f"{prefix}advanced.{field.alias or name}" if advanced and issubclass(model, AdvancedBlock) else key
        yield SettingRow(name=key, type=_type(field.annotation), default=_default(field), range=bounds,
                         unit=str(extra.get("unit", "")), description=" ".join((field.description or "").split()),
                         advanced=advanced, written=written)
        if section is not None:
            yield from setting_rows(section, f"{key}.")


def _subtree(model: type[BaseModel], section: str) -> type[BaseModel]:
    """The nested settings model at dotted ``section`` of ``model``; ValueError naming what exists."""
    for part in section.split("."):
        field = model.model_fields.get(part)
        sub = _section(_strip_none(field.annotation)[0]) if field is not None else None
        if sub is None:
            sections = [n for n, f in model.model_fields.items() if _section(_strip_none(f.annotation)[0])]
            raise ValueError(f"{model.__name__} has no section {part!r}; its sections: {', '.join(sections) or 'none'}")
        model = sub
    return model


def select_rows(model: type[BaseModel], section: str = "") -> list[SettingRow]:
    """The rows of ``model``, or of its nested ``section`` only (names still dotted from the top)."""
    if not section:
        return list(setting_rows(model))
    return list(setting_rows(_subtree(model, section), f"{section}."))


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _code(text: str) -> str:
    return f"`{text}`" if text else ""


def _table(rows: list[SettingRow]) -> list[str]:
    lines = ["| setting | default | range | unit | description |", "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {_code(r.written or r.name)} | {_cell(_code(r.default))} | {_cell(r.range or r.type)} | {_cell(r.unit)} "
                     f"| {_cell(r.description)} |")
    return lines


def markdown_table(model: type[BaseModel], section: str = "") -> str:
    """GitHub-markdown tables of ``model``'s settings (or of its nested ``section``): the ones an
    integrator sets, then, under a line saying so, the advanced ones (tuning)."""
    rows = select_rows(model, section)
    main = [r for r in rows if not r.advanced]
    advanced = [r for r in rows if r.advanced]
    lines = _table(main) if main else []
    if advanced:
        under = any(r.written != r.name for r in advanced)
        lines += ["", "Advanced (tuning; the defaults suit most robots" +
                  ("; written under their section's `advanced:`" if under else "") + "):", "", *_table(advanced)]
    return "\n".join(lines)


def _limits(row: SettingRow) -> str:
    """``default [unit], range``, as ``--help`` shows a setting."""
    default = f"{row.default} {row.unit}" if row.unit and row.default not in ("none", "required") else row.default
    return f"{default}; {row.range}" if row.range else default


def find_row(model: type[BaseModel], name: str) -> SettingRow:
    """The row of dotted setting ``name``; KeyError naming the settings there are."""
    rows = {r.name: r for r in setting_rows(model)}
    if name not in rows:
        raise KeyError(f"{model.__name__} has no setting {name!r}; it has {', '.join(rows)}")
    return rows[name]


def flag_help(model: type[BaseModel], name: str, text: str = "") -> str:
    """The help of a flag that sets ``model``'s setting ``name``: ``text`` (else the setting's
    description), then the setting's name, default, unit and range from its declaration."""
    row = find_row(model, name)
    head = text or row.description
    return f"{head} (setting {name}: default {_limits(row)})".replace("%", "%%")


def _wrap(text: str, width: int, indent: str, hang: str = "") -> list[str]:
    return textwrap.wrap(text, width, initial_indent=indent, subsequent_indent=indent + hang,
                         break_on_hyphens=False)


def settings_epilog(model: type[BaseModel], section: str, width: int = 79) -> str:
    """``--help``'s list of ``model``'s settings: each one an integrator sets with its default, unit,
    range and description, then the advanced ones, a line each; and where they are set."""
    env = f"PERCEPTION_{section.upper()}__"
    head = (f"settings (defaults; --service-config FILE, its '{section}' section; environment {env}<NAME>, "
            "'__' for each '.' of a nested name; then the flags):")
    lines = textwrap.wrap(head, width)
    rows = list(setting_rows(model))
    for r in (r for r in rows if not r.advanced):
        lines += _wrap(f"{r.name} = {_limits(r)}", width, "  ", "    ")
        if r.description:
            lines += _wrap(r.description, width, "      ")
    advanced = [r for r in rows if r.advanced]
    if advanced:
        lines.append("advanced settings (tuning):")
        for r in advanced:
            lines += _wrap(f"{r.written or r.name} = {_limits(r)}", width, "  ", "    ")
    return "\n".join(lines)


def add_settings_epilog(parser: argparse.ArgumentParser, model: type[BaseModel], section: str) -> None:
    """Put ``model``'s settings (:func:`settings_epilog`) at the end of ``parser``'s ``--help``, and
    give each flag whose destination is a setting's name that setting's name, default and range
    (:func:`flag_help`) after its own text, unless its help already names its setting."""
    parser.epilog = settings_epilog(model, section)
    rows = {r.name for r in setting_rows(model)}
    for action in parser._actions:
        if action.dest in rows and action.help != argparse.SUPPRESS and "(setting " not in (action.help or ""):
            action.help = flag_help(model, action.dest, (action.help or "").replace("%%", "%"))
    if parser.formatter_class is argparse.HelpFormatter:
        parser.formatter_class = argparse.RawDescriptionHelpFormatter

"""Typed settings, declared once: command-line flags generated from a config dataclass, its
fields' choices checked from their types, and the dataclass built back from nested mappings.

A field's help is the comment above it or at the end of its line; its choices are its
`Literal[...]` type, or `field(metadata={CHOICES: callable})` for a registry that grows at run
time. `rosutil.declare_dataclass` turns the same dataclasses into ROS parameters.
`OneLineParser` makes a command's usage mistakes one line and exit status 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import functools
import inspect
import io
import re
import tokenize
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any, Literal, NoReturn

FIELD_LINE = re.compile(r"    (\w+)\s*:")  # a field's declaration in its class body
CHOICES = "choices"  # field metadata key: a callable returning the allowed values (a registry's names)


@dataclasses.dataclass(frozen=True)
class FieldType:
    """What a field's annotation says a command line must give: the value type, its choices
    (None: any), and whether it is a tuple of such values."""

    kind: type
    choices: tuple[Any, ...] | None
    many: bool


@functools.cache
def field_types(cls: type) -> dict[str, FieldType | type]:
    """Each field's FieldType, or its dataclass for a nested settings dataclass."""
    hints = typing.get_type_hints(cls)
    found: dict[str, FieldType | type] = {}
    for field in dataclasses.fields(cls):
        hint = hints[field.name]
        if dataclasses.is_dataclass(hint):
            found[field.name] = hint
            continue
        many = typing.get_origin(hint) is tuple
        if many:
            hint = typing.get_args(hint)[0]
        if typing.get_origin(hint) in (typing.Union, types.UnionType):  # X | None
            hint = next(arg for arg in typing.get_args(hint) if arg is not type(None))
        choices = None
        if typing.get_origin(hint) is Literal:
            choices = typing.get_args(hint)
            hint = type(choices[0])
        found[field.name] = FieldType(hint, choices, many)
    return found


def field_choices(cls: type, name: str) -> tuple[Any, ...] | None:
    """The values field `name` of `cls` may take (its Literal type or its CHOICES metadata), or None."""
    field = next(field for field in dataclasses.fields(cls) if field.name == name)
    if CHOICES in field.metadata:
        return tuple(field.metadata[CHOICES]())
    described = field_types(cls)[name]
    return described.choices if isinstance(described, FieldType) else None


def check_choices(instance: Any, prefix: str = "") -> None:
    """Refuse, in one line, a field whose value is not one of its choices (call from __post_init__)."""
    cls = type(instance)
    for field in dataclasses.fields(cls):
        choices = field_choices(cls, field.name)
        if choices is None:
            continue
        values = getattr(instance, field.name)
        for value in values if isinstance(values, tuple) else (values,):
            if value not in choices and not (value is None and field.default is None):
                raise ValueError(f"unknown {prefix}{field.name} {value!r}; expected one of {choices}")


@functools.cache
def field_docs(cls: type) -> dict[str, str]:
    """Each field's comment: the `#` lines right above it, then the one at the end of its line."""
    try:
        source = inspect.getsource(cls)
    except (OSError, TypeError):
        return {}
    comments = {
        token.start[0]: token.string.lstrip("#").strip()
        for token in tokenize.generate_tokens(io.StringIO(source).readline)
        if token.type == tokenize.COMMENT
    }
    names = {field.name for field in dataclasses.fields(cls)}
    docs: dict[str, str] = {}
    above: list[str] = []
    for number, line in enumerate(source.splitlines(), start=1):
        declared = FIELD_LINE.match(line)
        if line.strip().startswith("#"):
            above.append(comments.get(number, ""))
        elif declared and declared[1] in names:
            trailing = [comments[number]] if number in comments else []
            docs[declared[1]] = " ".join(above + trailing)
            above = []
        else:
            above = []
    return {name: text for name, text in docs.items() if text}


def _parse_items(kind: type) -> Callable[[str], list[Any]]:
    """A token of a tuple flag as a list: "32,64" and "32" "64" both give [32, 64]."""

    def parse(text: str) -> list[Any]:
        return [kind(item) for item in text.split(",") if item]

    return parse


def _flatten(values: list[list[Any]] | None) -> tuple[Any, ...] | None:
    return None if values is None else tuple(item for items in values for item in items)


@dataclasses.dataclass
class SettingFlags:
    """The flags `add_setting_flags` made: dest (a dotted setting path) -> the field's FieldType."""

    fields: dict[str, FieldType] = dataclasses.field(default_factory=dict)

    def overrides(self, args: argparse.Namespace) -> dict[str, Any]:
        """The settings the command line gave, nested like the dataclass (flags not given are absent)."""
        nested: dict[str, Any] = {}
        for path, described in self.fields.items():
            value = getattr(args, path)
            if value is None:
                continue
            if described.many:
                value = _flatten(value)
            *parents, name = path.split(".")
            target = nested
            for parent in parents:
                target = target.setdefault(parent, {})
            target[name] = value
        return nested


def add_setting_flags(
    parser: argparse.ArgumentParser,
    cls: type,
    *,
    prefixes: Mapping[str, str] | None = None,
    flags: Mapping[str, str] | None = None,
    skip: tuple[str, ...] = (),
    added: SettingFlags | None = None,
    path: str = "",
) -> SettingFlags:
    """One flag per field of `cls` and of its nested settings dataclasses, help from the fields'
    comments, types and choices from their annotations, every default None (a flag not given
    leaves the setting to the config file or the dataclass). Names: `--field-name`, a nested
    field's prefixed by its parent's name (`--sac-batch-size`) unless `prefixes` maps the parent's
    dotted path to another prefix ("" for none); `flags` renames single settings
    ({"encoder.kind": "encoder"}); `skip` leaves dotted paths (and their children) out."""
    prefixes, flags = prefixes or {}, flags or {}
    added = added if added is not None else SettingFlags()
    docs = field_docs(cls)
    defaults = cls.__dataclass_fields__
    for name, described in field_types(cls).items():
        dotted = f"{path}{name}"
        if dotted in skip:
            continue
        if isinstance(described, type):  # a nested dataclass
            add_setting_flags(
                parser, described, prefixes=prefixes, flags=flags, skip=skip, added=added, path=f"{dotted}."
            )
            continue
        flag = "--" + flags.get(dotted, _flag_name(dotted, prefixes))
        default = _default_of(defaults[name])
        text = docs.get(name, "")
        shown = list(default) if isinstance(default, tuple) else default
        help_text = f"{text} (default: {shown})" if text else f"default: {shown}"
        choices = field_choices(cls, name)
        options: dict[str, Any] = {"dest": dotted, "default": None, "help": help_text.replace("%", "%%")}
        if described.kind is bool and not described.many:
            options["action"] = argparse.BooleanOptionalAction
        elif described.many:
            options.update(type=_parse_items(described.kind), nargs="*", metavar=name.upper())
        else:
            options.update(type=described.kind, choices=choices)
            if choices is None:
                options["metavar"] = name.upper()
        parser.add_argument(flag, **options)
        added.fields[dotted] = described
    return added


def _flag_name(dotted: str, prefixes: Mapping[str, str]) -> str:
    """`--` less flag name of a dotted setting: each parent adds its prefix (its name by default)."""
    parts = dotted.split(".")
    name = ""
    for depth in range(1, len(parts)):
        parent = ".".join(parts[:depth])
        name += prefixes.get(parent, f"{parts[depth - 1].replace('_', '-')}-")
    return name + parts[-1].replace("_", "-")


def _default_of(field: dataclasses.Field) -> Any:
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    return None


class OneLineParser(argparse.ArgumentParser):
    """Usage mistakes (an unknown flag, a missing value, a bad choice or type, `parser.error`) as
    one line, `PROGRAM: what is wrong`, and exit status 2, like every other bad input: argparse's
    own message puts the whole usage, a dozen lines for a command with many flags, before it."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog.split()[0]}: {message}\n")  # a subcommand's errors name the program


def reject_unknown(data: Mapping[Any, Any], cls: type, what: str) -> None:
    """One ValueError naming the keys of `data` that are no field of the dataclass `cls`, with the
    closest field to the first of them."""
    known = {field.name for field in dataclasses.fields(cls)}
    unknown = sorted(set(data) - known, key=str)
    if unknown:
        close = difflib.get_close_matches(str(unknown[0]), known, 1)
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise ValueError(f"unknown {what} {unknown}{hint}; expected some of {sorted(known)}")


def build_settings(cls: type, data: Mapping[str, Any], what: str = "setting(s)") -> Any:
    """`cls` from a nested mapping (a YAML file, merged flags): nested dataclasses from their
    mappings, lists as tuples; an unknown key or a value of the wrong kind is one ValueError."""
    reject_unknown(data, cls, what)
    values: dict[str, Any] = {}
    for name, value in data.items():
        described = field_types(cls)[name]
        if isinstance(described, type) and isinstance(value, Mapping):
            value = build_settings(described, value, f"{name} setting(s)")
        elif isinstance(value, list):
            value = tuple(value)
        values[name] = value
    try:
        return cls(**values)
    except TypeError as error:  # e.g. a string where a number belongs, a required field missing
        raise ValueError(f"a setting has the wrong type or is missing ({error})") from None

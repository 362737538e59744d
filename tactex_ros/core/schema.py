"""The schema machinery of every setting (pydantic v2): learner, trial, scene and node parameters.

A settings class derives from ``Schema``; each field carries its type, default, range
(``param(..., lo, hi)``), choices (a ``Literal`` type) and description. The same declaration
validates configs and files (errors located like ``platforms.2.position`` and naming the field),
gives the ROS nodes their parameter descriptors (``nodes/lifecycle.declare_settings``), the
command line its options and the launch file its arguments (``fields``). The one override
syntax (``overrides``: dotted schema paths such as ``learner.lr=1e-3``) lives here too; the
settings themselves are in ``core/config.py``.
"""

from __future__ import annotations

import difflib
import typing
from dataclasses import dataclass, replace
from typing import Annotated, Any, Literal, Union

import annotated_types
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError

from .errors import InputError

TAG = "model"       # the field that tells the members of a union apart (the learners')


def param(default: Any, description: str, lo: float | None = None, hi: float | None = None,
          **kw: Any) -> Any:
    """A schema field: default, description and optional inclusive range [lo, hi]. Choices are
    the field's ``Literal`` type; ``read_only=True`` marks a ROS parameter fixed at start-up."""
    extra = {"read_only": True} if kw.pop("read_only", False) else None
    return Field(default, description=description, ge=lo, le=hi, json_schema_extra=extra, **kw)


class FieldError(ValueError):
    """Raised by a cross-field check: ``field`` is added to the error's location."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field


class Schema(BaseModel):
    """Base of every settings model. Strict types (an int is taken where a float is expected;
    a bool or a string for a number is not), unknown names refused, frozen (validated once
    where the settings enter; ``replace`` makes a validated copy). Constructing one with bad
    values raises InputError naming the field."""

    model_config = ConfigDict(strict=True, extra="forbid", frozen=True, validate_default=True)

    def __init__(self, **data: Any) -> None:
        try:
            super().__init__(**data)
        except ValidationError as exc:
            raise located(exc, type(self).__name__, type(self)) from None

    @classmethod
    def check(cls, data: Any, origin: str | None = None) -> Any:
        """``data`` (a mapping) validated into ``cls``; InputError names every bad field as
        ``origin: location: problem``."""
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            raise located(exc, origin or cls.__name__, cls) from None

    def replace(self, **kw: Any) -> Any:
        """A validated copy with ``kw`` changed."""
        return type(self).check({**self.model_dump(), **kw}, type(self).__name__)


def variants(ann: Any) -> dict[str, type]:
    """{tag: schema class} of a union of schema classes told apart by their ``TAG`` field
    (``LearnerSettings``); empty when ``ann`` is not one."""
    if typing.get_origin(ann) is Annotated:
        ann = typing.get_args(ann)[0]
    if typing.get_origin(ann) is not Union:
        return {}
    out: dict[str, type] = {}
    for c in typing.get_args(ann):
        if isinstance(c, type) and issubclass(c, BaseModel) and TAG in c.model_fields:
            out.update(dict.fromkeys(typing.get_args(c.model_fields[TAG].annotation), c))
    return out


def _inner(ann: Any) -> Any:
    """What a field of annotation ``ann`` holds for locating errors: a schema class, a union
    of them (``variants``), or None."""
    if variants(ann) or (isinstance(ann, type) and issubclass(ann, BaseModel)):
        return ann
    return next((a for a in typing.get_args(ann)
                 if isinstance(a, type) and issubclass(a, BaseModel)), None)


def _walk(root: Any, loc: tuple) -> tuple[tuple, Any, str | None]:
    """``loc`` without the union tags pydantic puts in it (``learner.descriptor.lr`` ->
    ``learner.lr``), the schema class (or union) that holds its last part, and the last tag
    passed."""
    out, cur, tag = [], root, None
    for part in loc:
        tags = variants(cur)
        if tags and part in tags:
            cur, tag = tags[part], part   # the tag of the union member: not a field name
            continue
        out.append(part)
        if isinstance(part, int):
            continue
        f = cur.model_fields.get(part) if isinstance(cur, type) and issubclass(
            cur, BaseModel) else None
        cur = None if f is None else _inner(f.annotation)
    return tuple(out), cur, tag


class SchemaError(InputError):
    """Bad settings: ``problems`` lists (location, problem) pairs; the message names them all."""

    def __init__(self, origin: str, problems: list[tuple[tuple, str]]) -> None:
        self.origin, self.problems = origin, problems
        super().__init__(f"{origin}: " + "; ".join(
            f"{'.'.join(map(str, loc))}: {msg}" if loc else msg for loc, msg in problems))


def located(exc: ValidationError, origin: str, cls: type | None = None) -> SchemaError:
    """A pydantic error as SchemaError: ``origin: a.2.b: problem (got value)``, every error."""
    out: list[tuple[tuple, str]] = []
    for e in exc.errors():
        loc, holder, _ = _walk(cls, tuple(e["loc"])[:-1])
        loc += tuple(e["loc"])[-1:]
        err = (e.get("ctx") or {}).get("error")
        if isinstance(err, SchemaError):      # a nested schema's own check (its __init__)
            loc = _walk(cls, tuple(e["loc"]))[0]
            out += [(loc + sub, msg) for sub, msg in err.problems]
            continue
        if isinstance(err, FieldError):
            loc, msg = loc + (err.field,), str(err)
        elif isinstance(err, Exception):
            msg = str(err)
        elif e["type"] == "extra_forbidden":
            kind = getattr(holder, "kind", "")
            msg = "unknown name" + (f" for a {kind} learner" if kind else "") + (
                f"; known: {', '.join(holder.model_fields)}"
                if isinstance(holder, type) and issubclass(holder, BaseModel) else "")
        elif e["type"] == "union_tag_invalid":
            loc, union, _ = _walk(cls, tuple(e["loc"]))
            *head, last = map(repr, variants(union) or [e["ctx"]["expected_tags"]])
            loc, msg = loc + (TAG,), (f"Input should be {', '.join(head)}"
                                      f"{' or ' if head else ''}{last} (got {e['ctx']['tag']!r})")
        else:
            msg = f"{e['msg']} (got {e['input']!r})" if e["type"] != "missing" else e["msg"]
        out.append((loc, msg))
    return SchemaError(origin, out)


@dataclass(frozen=True)
class FieldSpec:
    """One scalar schema field: dotted ``name``, Python ``kind`` (bool, int, float, str),
    default, inclusive range, choices, description, read-only (a ROS parameter fixed at
    start-up)."""

    name: str
    kind: type
    default: Any
    lo: float | None
    hi: float | None
    choices: tuple
    description: str
    read_only: bool
    tag: bool = False             # it picks the member of a union (``learner.model``)
    learners: tuple[str, ...] = ()   # the learner families that have it ('' = every one)


def fields(cls: type, prefix: str = "", values: dict[str, Any] | None = None) -> list[FieldSpec]:
    """The scalar fields of a schema class, nested schemas as dotted names (``trial.rounds``),
    in declaration order. A union of learners' settings: the fields of the member ``values``
    (nested settings, e.g. a model dump) names by its tag, or else of every member, each name
    once with the families that have it (``FieldSpec.learners``)."""
    out: list[FieldSpec] = []
    for name, f in cls.model_fields.items():
        ann = f.annotation
        sub = (values or {}).get(name)
        tags = variants(ann)
        if tags:
            out += _union_fields(tags, f"{prefix}{name}.", sub if isinstance(sub, dict) else None)
            continue
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            out += fields(ann, f"{prefix}{name}.", sub if isinstance(sub, dict) else None)
            continue
        choices = typing.get_args(ann) if typing.get_origin(ann) is Literal else ()
        kind = type(choices[0]) if choices else ann
        lo = next((m.ge for m in f.metadata if isinstance(m, annotated_types.Ge)), None)
        hi = next((m.le for m in f.metadata if isinstance(m, annotated_types.Le)), None)
        extra = f.json_schema_extra if isinstance(f.json_schema_extra, dict) else {}
        out.append(FieldSpec(f"{prefix}{name}", kind, f.get_default(call_default_factory=True),
                             lo, hi, choices, f.description or "",
                             bool(extra.get("read_only"))))
    return out


def _union_fields(tags: dict[str, type], prefix: str,
                  values: dict[str, Any] | None) -> list[FieldSpec]:
    """``fields`` of a union's member named by ``values[TAG]``, or of every member; the tag
    field lists every member's tag as its choices."""
    members = list(dict.fromkeys(tags.values()))
    chosen = tags.get((values or {}).get(TAG))
    out: dict[str, FieldSpec] = {}
    for c in [chosen] if chosen else members:
        for s in fields(c, prefix, values):
            if s.name in out:
                prev = out[s.name]
                out[s.name] = replace(prev, learners=prev.learners + (c.kind,))
            else:
                out[s.name] = replace(s, learners=(c.kind,))
    tag = out[prefix + TAG]
    out[prefix + TAG] = replace(tag, choices=tuple(tags), tag=True, learners=(), read_only=True,
                                default=members[0].model_fields[TAG].default)
    if not chosen:
        out = {k: replace(s, learners=() if len(s.learners) == len(members) else s.learners)
               for k, s in out.items()}
    return list(out.values())


def field_spec(cls: type, name: str) -> FieldSpec:
    """The ``FieldSpec`` of the dotted field ``name`` of ``cls``."""
    for spec in fields(cls):
        if spec.name == name:
            return spec
    raise InputError(f"{cls.__name__} has no setting {name!r}")


def parse_text(cls: type, name: str, text: str, origin: str) -> Any:
    """The dotted field ``name`` of ``cls`` read from ``text`` (e.g. a launch argument) and
    checked against its type, range and choices; InputError names ``origin``. In a union of
    learners' settings the first member that has the field types it (the tag takes every
    member's)."""
    *heads, last = name.split(".")
    ann: Any = cls
    for part in heads:
        ann = _holder(ann, part).model_fields[part].annotation
    tags = variants(ann)
    if tags and last == TAG:
        ann, info = Literal[tuple(tags)], Field()
    else:
        info = _holder(ann, last).model_fields[last]
        ann = info.annotation
    try:
        return TypeAdapter(Annotated[ann, info]).validate_strings(text)
    except ValidationError as exc:
        raise located(exc, origin) from None


def _holder(ann: Any, name: str) -> type:
    """The schema class ``ann`` or the first member of the union ``ann`` with field ``name``."""
    for c in list(dict.fromkeys(variants(ann).values())) or [ann]:
        if name in c.model_fields:
            return c
    raise InputError(f"no setting {name!r}")


def nearest(path: str, known: list[str]) -> str:
    """The name in ``known`` closest to ``path``: one with the same last part
    (``lr`` -> ``learner.lr``), else the most similar spelling."""
    same = [k for k in known if k.rsplit(".", 1)[-1] == path.rsplit(".", 1)[-1]]
    return (same or difflib.get_close_matches(path, known, n=1, cutoff=0.0) or [""])[0]


def overrides(cls: type, items: list[str] | None, option: str = "--set") -> dict[str, Any]:
    """The one override syntax: ``PATH=VALUE`` items, each ``PATH`` a dotted field of ``cls``
    (``learner.lr=1e-3``, ``trial.strategy=infogain``) and each value read as that field's
    type (``parse_text``). Returns nested settings (``{"learner": {"lr": 0.001}}``); a later
    item wins. InputError (exit status 2) names ``option``, the item and, for an unknown path,
    the nearest valid one. Whether a field fits the learner chosen is the settings' check."""
    known = [s.name for s in fields(cls)]
    flat: dict[str, Any] = {}
    for item in items or []:
        path, sep, text = item.partition("=")
        path = path.strip()
        if not sep or not path:
            raise InputError(f"{option} {item!r}: expected PATH=VALUE, e.g. learner.lr=1e-3")
        if path not in known:
            raise InputError(f"{option} {item!r}: unknown setting {path!r}; nearest valid: "
                             f"{nearest(path, known)!r}")
        flat[path] = parse_text(cls, path, text.strip(), f"{option} {item!r}")
    return nest(flat)


def nest(flat: dict[str, Any]) -> dict[str, Any]:
    """``{"trial.rounds": 2}`` -> ``{"trial": {"rounds": 2}}``."""
    out: dict[str, Any] = {}
    for key, value in flat.items():
        *heads, last = key.split(".")
        d = out
        for h in heads:
            d = d.setdefault(h, {})
        d[last] = value
    return out


def flatten(nested: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"trial": {"rounds": 2}}`` -> ``{"trial.rounds": 2}``."""
    out: dict[str, Any] = {}
    for key, value in nested.items():
        if isinstance(value, dict):
            out.update(flatten(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def merge(*dicts: dict[str, Any] | None) -> dict[str, Any]:
    """Nested mappings merged left to right (a later value wins; nested mappings merge)."""
    return nest({k: v for d in dicts if d for k, v in flatten(d).items()})


def typed(cls: type, given: dict[str, Any], origin: str | None = None) -> dict[str, Any]:
    """``given`` (nested, a subset of ``cls``'s fields) checked against ``cls`` and returned with
    the schema's types (an int given for a float comes back as a float), e.g. for a ROS
    parameters file. InputError names the field."""
    model = cls.check(given, origin)
    dumped = flatten(model.model_dump())
    return nest({k: dumped[k] for k in flatten(given)})


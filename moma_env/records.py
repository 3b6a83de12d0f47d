"""Frozen slotted dataclasses made cheaper to construct.

The simulator makes several small immutable records at every step (a camera's
detections, the estimator's snapshot of each robot, the frame, the observer's state,
the reward's step). The ``__init__`` that ``@dataclass(frozen=True)`` generates sets
each field through ``object.__setattr__``, so that the class's own ``__setattr__``
(which raises ``FrozenInstanceError``) is bypassed; a slotted class's slot descriptors
have setters of their own that do the same thing at about half the cost.
:func:`slot_setter_init` gives such a class an ``__init__`` that calls them: the same
parameters, defaults and annotations, the same stored values, only the way each
field is stored differs.

This module imports only the standard library: the estimator uses it too.
"""

from __future__ import annotations

import dataclasses
from typing import TypeVar

__all__ = ["slot_setter_init"]

_Record = TypeVar("_Record", bound=type)


def slot_setter_init(cls: _Record) -> _Record:
    """Class decorator, applied over ``@dataclass(frozen=True, slots=True)``: replace the
    generated ``__init__`` with one that stores each field through its slot's setter.

    The new ``__init__`` takes the fields as the generated one does (positional or
    keyword, in field order, with the same defaults) and has the same annotations,
    so ``inspect.signature``, ``dataclasses.replace``, pickling, equality and the
    frozen instances' ``FrozenInstanceError`` are unchanged.

    Raises:
        TypeError: ``cls`` is not a frozen slotted dataclass, or has what the new
            ``__init__`` would not reproduce: a ``__post_init__``, a field left out
            of ``__init__`` (``init=False``), a keyword-only field or a
            ``default_factory``.
    """
    name = getattr(cls, "__qualname__", repr(cls))
    if not dataclasses.is_dataclass(cls) or not isinstance(cls, type):
        raise TypeError(f"slot_setter_init: {name} is not a dataclass")
    if not cls.__dataclass_params__.frozen or "__slots__" not in cls.__dict__:
        raise TypeError(f"slot_setter_init: {name} must be @dataclass(frozen=True, slots=True)")
    if hasattr(cls, "__post_init__"):
        raise TypeError(f"slot_setter_init: {name} has a __post_init__, which this __init__ would not call")
    namespace: dict[str, object] = {}
    parameters: list[str] = []
    body: list[str] = []
    annotations: dict[str, object] = {}
    for field in dataclasses.fields(cls):
        if not field.init or field.kw_only or field.default_factory is not dataclasses.MISSING:
            raise TypeError(
                f"slot_setter_init: field {name}.{field.name} must be a plain field "
                "(in __init__, positional, no default_factory)"
            )
        namespace[f"_set_{field.name}"] = cls.__dict__[field.name].__set__
        if field.default is dataclasses.MISSING:
            parameters.append(field.name)
        else:
            namespace[f"_default_{field.name}"] = field.default
            parameters.append(f"{field.name}=_default_{field.name}")
        body.append(f"    _set_{field.name}(self, {field.name})")
        annotations[field.name] = field.type
    annotations["return"] = None
    source = f"def __init__(self, {', '.join(parameters)}):\n" + ("\n".join(body) if body else "    pass") + "\n"
    exec(source, namespace)  # noqa: S102 - the source is built above from the field names alone
    init = namespace["__init__"]
    init.__qualname__ = f"{cls.__qualname__}.__init__"
    init.__module__ = cls.__module__
    init.__annotations__ = annotations
    init.__doc__ = f"Store the fields of {cls.__name__} (through the slots' setters)."
    cls.__init__ = init
    return cls

"""``moma_env.records.slot_setter_init``: the records it gives an ``__init__`` behave as the
``__init__`` ``@dataclass(frozen=True, slots=True)`` generates (the reference: the same
fields made by ``dataclasses.make_dataclass``), and it refuses what it would not reproduce."""

import copy
import dataclasses
import inspect
import pickle

import pytest

from moma_env.camera import MeasureRequest
from moma_env.env.rewards import RewardStep
from moma_env.estimator import Detection, RobotEstimate
from moma_env.records import slot_setter_init
from moma_env.sim import Frame
from moma_env.world import UAVState

RECORDS = (Detection, RobotEstimate, Frame, UAVState, RewardStep, MeasureRequest)


def reference_class(cls):
    """A frozen slotted dataclass with ``cls``'s fields, equality rule and the generated ``__init__``."""
    specs = []
    for f in dataclasses.fields(cls):
        if f.default is dataclasses.MISSING:
            specs.append((f.name, f.type))
        else:
            specs.append((f.name, f.type, dataclasses.field(default=f.default)))
    eq = cls.__dataclass_params__.eq
    return dataclasses.make_dataclass("Reference" + cls.__name__, specs, frozen=True, eq=eq, slots=True)


def field_values(record):
    return [getattr(record, f.name) for f in dataclasses.fields(record)]


@pytest.mark.parametrize("cls", RECORDS, ids=lambda c: c.__name__)
def test_the_record_is_the_generated_one(cls):
    Reference = reference_class(cls)
    fields = dataclasses.fields(cls)
    required = sum(f.default is dataclasses.MISSING for f in fields)
    ours = inspect.signature(cls.__init__).parameters
    theirs = inspect.signature(Reference.__init__).parameters
    assert [(p.name, p.kind, p.default, p.annotation) for p in ours.values()] == [
        (p.name, p.kind, p.default, p.annotation) for p in theirs.values()
    ]
    for n in range(required, len(fields) + 1):
        args = [(f.name, i) for i, f in enumerate(fields[:n])]  # picklable, distinct values
        record = cls(*[v for _, v in args])
        reference = Reference(*[v for _, v in args])
        assert field_values(record) == field_values(reference)
        for f in fields[n:]:  # the defaults, the very objects
            assert getattr(record, f.name) is f.default
        by_name = cls(**dict(args))
        assert field_values(by_name) == field_values(record)
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(record, fields[0].name, "changed")
    changed = dataclasses.replace(record, **{fields[0].name: "changed"})
    assert type(changed) is cls and getattr(changed, fields[0].name) == "changed"
    assert field_values(changed)[1:] == field_values(record)[1:]
    for twin in (pickle.loads(pickle.dumps(record)), copy.deepcopy(record)):
        assert field_values(twin) == field_values(record)
    assert repr(record).split("(", 1)[1] == repr(reference).split("(", 1)[1]
    if cls.__dataclass_params__.eq:
        assert record == cls(*field_values(record))


@pytest.mark.parametrize("cls", RECORDS, ids=lambda c: c.__name__)
def test_argument_errors_are_the_generated_ones(cls):
    Reference = reference_class(cls)
    required = [f.name for f in dataclasses.fields(cls) if f.default is dataclasses.MISSING]
    for call in (
        lambda c: c(),
        lambda c: c(*range(len(dataclasses.fields(cls)) + 1)),
        lambda c: c(*range(len(required)), not_a_field=1),
    ):
        with pytest.raises(TypeError) as ours:
            call(cls)
        with pytest.raises(TypeError) as theirs:
            call(Reference)
        assert str(ours.value).split("__init__() ", 1)[1] == str(theirs.value).split("__init__() ", 1)[1]


def test_refuses_what_it_would_not_reproduce():
    @dataclasses.dataclass(frozen=True)
    class NotSlotted:
        x: int

    @dataclasses.dataclass(slots=True)
    class NotFrozen:
        x: int

    @dataclasses.dataclass(frozen=True, slots=True)
    class PostInit:
        x: int

        def __post_init__(self) -> None:
            pass

    @dataclasses.dataclass(frozen=True, slots=True)
    class Factory:
        x: list = dataclasses.field(default_factory=list)

    @dataclasses.dataclass(frozen=True, slots=True)
    class KeywordOnly:
        x: int = dataclasses.field(kw_only=True)

    @dataclasses.dataclass(frozen=True, slots=True)
    class NotInInit:
        x: int = dataclasses.field(default=0, init=False)

    class Plain:
        pass

    for cls, words in (
        (NotSlotted, "frozen=True, slots=True"),
        (NotFrozen, "frozen=True, slots=True"),
        (PostInit, "__post_init__"),
        (Factory, "Factory.x"),
        (KeywordOnly, "KeywordOnly.x"),
        (NotInInit, "NotInInit.x"),
        (Plain, "not a dataclass"),
    ):
        with pytest.raises(TypeError, match=words.replace("(", r"\(")):
            slot_setter_init(cls)


def test_a_record_without_fields():
    @slot_setter_init
    @dataclasses.dataclass(frozen=True, slots=True)
    class Empty:
        pass

    assert isinstance(Empty(), Empty)
    with pytest.raises(TypeError):
        Empty(1)

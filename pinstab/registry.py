"""Registries of extensions: constraint kinds, force kinds, stabilizers, solvers, integrators.

Every extension registers a name with a factory and an options dataclass; the scene reader, the
``simulate()`` API and the command line look extensions up here instead of naming them, so adding
one is one new module plus one registration (see docs/guide/extending.md)::

    @STABILIZERS.register("my-method", options=MyOptions, summary="what it does")
    class MyStabilizer(Stabilizer):
        def __init__(self, options: MyOptions) -> None: ...

A registry iterates over its names, so it serves directly as ``argparse`` choices.
"""

from __future__ import annotations

import dataclasses
import importlib
import pkgutil
import typing
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from .errors import PinstabError, choices

T = TypeVar("T")


@dataclass(frozen=True)
class NoOptions:
    """The options of an extension that takes none."""


@dataclass(frozen=True)
class OptionField:
    """One option of an extension, as the command line shows it.

    Attributes:
        name: the options dataclass field. flag: the command-line flag (``--kp``).
        kind: ``float``, ``int``, ``str`` or ``bool``. default: the dataclass default.
        help: text from the field's ``metadata["help"]``. choices: allowed strings, if any.
    """

    name: str
    flag: str
    kind: type
    default: Any
    help: str
    choices: tuple[str, ...] | None


def option_fields(options: type) -> list[OptionField]:
    """The fields of an options dataclass, with their flag, scalar type and help."""
    hints = typing.get_type_hints(options)
    found = []
    for item in dataclasses.fields(options):
        kinds = [k for k in typing.get_args(hints[item.name]) or (hints[item.name],) if k is not type(None)]
        kind = kinds[0] if kinds and kinds[0] in (float, int, str, bool) else str
        default = item.default if item.default is not dataclasses.MISSING else None
        flag = item.metadata.get("flag", "--" + item.name.replace("_", "-"))
        found.append(
            OptionField(item.name, flag, kind, default, item.metadata.get("help", ""), item.metadata.get("choices"))
        )
    return found


@dataclass(frozen=True)
class Entry(Generic[T]):
    """A registered extension.

    Attributes:
        name: the name users give. factory: builds the extension (its last argument is the options).
        options: the options dataclass. summary: one line for listings. kind: e.g. ``method``.
        capabilities: what the extension supports, to be asked before one is built (a solver's row kinds).
    """

    name: str
    factory: Callable[..., T]
    options: type
    summary: str
    kind: str
    capabilities: frozenset = frozenset()


class Registry(Generic[T]):
    """Names -> :class:`Entry`, in registration order.

    Args:
        kind: what an entry is called in messages (``method``, ``solver``, ...).
    """

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._entries: dict[str, Entry[T]] = {}

    def register(
        self,
        name: str,
        factory: Callable[..., T] | None = None,
        *,
        options: type = NoOptions,
        summary: str = "",
        capabilities: frozenset | set | tuple = frozenset(),
        replace: bool = False,
    ) -> Any:
        """Register ``factory`` under ``name``; without ``factory``, a decorator that registers what it
        decorates (a class or a function) and returns it unchanged.

        Raises:
            PinstabError: the name is taken (unless ``replace``), or ``options`` is not a dataclass.
        """
        if not dataclasses.is_dataclass(options):
            raise PinstabError(f"{self.kind} {name!r}: options must be a dataclass, got {options!r}")

        def add(target: Callable[..., T]) -> Callable[..., T]:
            if name in self._entries and not replace:
                raise PinstabError(f"{self.kind} {name!r} is already registered; pass replace=True to override it")
            self._entries[name] = Entry(name, target, options, summary, self.kind, frozenset(capabilities))
            return target

        return add if factory is None else add(factory)

    def unregister(self, name: str) -> None:
        """Remove an entry (e.g. one a test registered)."""
        self.entry(name)
        del self._entries[name]

    def entry(self, name: str) -> Entry[T]:
        """The entry of ``name``; PinstabError listing the registered names otherwise."""
        if not isinstance(name, str) or name not in self._entries:
            raise PinstabError(f"unknown {self.kind} {name!r}; valid {self.kind}s: {choices(self._entries)}")
        return self._entries[name]

    def entries(self) -> list[Entry[T]]:
        """Every entry, in registration order."""
        return list(self._entries.values())

    def make_options(self, name: str, given: Mapping[str, Any] | Any | None = None) -> Any:
        """The options dataclass of ``name`` from a mapping (an unknown option is refused, naming the
        options it takes and the entries that take the unknown one), an instance (returned as it is)
        or None (the defaults)."""
        entry = self.entry(name)
        if given is None:
            given = {}
        if isinstance(given, entry.options):
            return given
        if not isinstance(given, Mapping):
            raise PinstabError(f"{self.kind} {name!r}: options must be a mapping or {entry.options.__name__}")
        valid = [f.name for f in dataclasses.fields(entry.options)]
        unknown = sorted(set(given) - set(valid))
        if unknown:
            takes = f"its options: {choices(valid)}" if valid else "it takes no options"
            takers = [e.name for e in self.entries() if unknown[0] in {f.name for f in dataclasses.fields(e.options)}]
            elsewhere = f"; {unknown[0]!r} applies to {self.kind}s {choices(takers)}" if takers else ""
            raise PinstabError(f"{self.kind} {name!r} takes no option {unknown[0]!r} ({takes}){elsewhere}")
        try:
            return entry.options(**given)
        except (TypeError, ValueError) as exc:
            raise PinstabError(f"{self.kind} {name!r}: {exc}") from None

    def build(self, name: str, *arguments: Any, options: Mapping[str, Any] | Any | None = None) -> T:
        """``factory(*arguments, options)`` of entry ``name`` with its options checked."""
        return self.entry(name).factory(*arguments, self.make_options(name, options))

    def __iter__(self) -> Iterator[str]:
        return iter(list(self._entries))

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in self._entries

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return f"Registry({self.kind}: {', '.join(self._entries)})"


def load_extensions(package: str, path: list[str]) -> None:
    """Import every public module of a package (``__path__``), so that each registers itself: a new
    extension module needs no import line elsewhere."""
    for module in pkgutil.iter_modules(path):
        if not module.name.startswith("_"):
            importlib.import_module(f"{package}.{module.name}")

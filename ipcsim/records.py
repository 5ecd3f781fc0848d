"""Records whose equality is their meaning.

ipcsim's values are msgspec ``Struct``s, most of them frozen: made once, replaced
(``msgspec.structs.replace``) rather than written to. A frozen Struct compares and hashes
all its fields. A value that also records where it was written (a scene line, a path
as typed, the reader's warnings) compares and hashes by what it means instead: a
``ByMeaning`` record leaves its ``provenance`` fields out. Two scenes that say the same
in different files are equal.
"""

from __future__ import annotations

from typing import ClassVar


class ByMeaning:
    """Equality and hash over the fields not named in ``provenance`` (a mix-in of frozen
    Structs: ``class S(ByMeaning, Struct, frozen=True)``)."""

    __slots__ = ()
    provenance: ClassVar[tuple[str, ...]] = ()

    def _meaning(self) -> tuple:
        return tuple(getattr(self, name) for name in self.__struct_fields__
                     if name not in self.provenance)

    def __eq__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        return self._meaning() == other._meaning()

    def __hash__(self):
        return hash(self._meaning())

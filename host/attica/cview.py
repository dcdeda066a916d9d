"""Live views of C memory that keep the memory's owner alive (the binding's answer to cffi lifetimes).

cffi frees the memory of an ``ffi.new`` object when that object is garbage-collected, and a cdata
taken from it (a struct member ``p.u``, an array element ``a[3]``, ``p[0]``, ``ffi.addressof(p, ...)``)
does not keep it alive. So ``native.Filter("mekf", 0.01).state.u.mekf.c`` would point into freed
memory as soon as the temporary Filter is collected, and read whatever the next ``ffi.new`` puts
there (another filter's coefficients, typically).

A :class:`CView` holds the owning cdata beside the cdata it views, and every view it hands out
(members, elements, slices, :attr:`CView.ptr`) holds it too: a value obtained through a CView is
valid for as long as it is referenced, whatever happens to the object it came from.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

_AGGREGATE = ("struct", "union", "array", "pointer")


class _KeepAlive:
    """A no-op ``ffi.gc`` destructor whose only job is to hold a reference to the owner."""

    __slots__ = ("owner",)

    def __init__(self, owner: Any) -> None:
        self.owner = owner

    def __call__(self, _cdata: Any) -> None:
        """Release nothing: the owner frees its own memory once the last holder is gone."""


def _unwrap(value: Any) -> Any:
    return value._cdata if isinstance(value, CView) else value


class CView:
    """A live view of a C struct, union, array or pointer that keeps the owner of its memory alive.

    Reading a field or element gives a Python number for a scalar and another :class:`CView` for a
    struct, union, array or pointer; assigning writes through to the C memory (a CView or cdata of
    the same struct type copies the whole struct, as in C). Nothing is copied on reading: the view
    shows the C memory as it is now, and sees every later change made by C or through another view.
    :meth:`copy` takes a snapshot instead.

    For C calls, :attr:`ptr` is the underlying cffi pointer (an array for array views), itself
    holding the owner alive, e.g. ``lib.att_filter_reset(f.state.ptr)``. Members taken from that raw
    cdata follow cffi's rules and do *not* hold the owner: take them from the view. (A C field named
    like an attribute of the view itself, ``ptr``, ``copy`` or ``ctype``, is read as ``view.ptr.name``.)

    Parameters
    ----------
    cdata
        The viewed cdata (struct or union reference, array or pointer).
    owner
        The cdata that owns the memory (an ``ffi.new`` result) or any object keeping it alive.
    ffi
        The ``cffi.FFI`` instance the cdata belongs to.

    Raises
    ------
    TypeError
        ``cdata`` is a scalar or function (nothing to view).

    """

    __slots__ = ("_cdata", "_owner", "_ffi")

    def __new__(cls, cdata: Any, owner: Any, ffi: Any) -> CView:
        """A view of the right class for the cdata's type (its fields as attributes)."""
        t = ffi.typeof(cdata)
        sub = _view_class(t)
        if sub is None:
            raise TypeError(f"CView: a {t.kind} cdata ({t.cname}) has no members to view")
        return _make(sub, cdata, owner, ffi)

    # --- what the view is ---------------------------------------------------------------------

    @property
    def ctype(self) -> Any:
        """The cffi type of the viewed cdata (``ffi.typeof``), e.g. ``<ctype 'att_filter_t *'>``."""
        return self._ffi.typeof(self._cdata)

    @property
    def ptr(self) -> Any:
        """The cffi pointer to the viewed memory (an array for array views), for C calls and ffi.

        A struct or union view gives a pointer to it (``ffi.addressof``). The returned cdata keeps
        the owner alive while it is referenced (``ffi.gc`` with a no-op destructor); cdata taken
        from it (members, elements) does not, as everywhere in cffi.
        """
        return self._ffi.gc(self._source(), _KeepAlive(self._owner))

    def _source(self) -> Any:
        ffi = self._ffi
        c = self._cdata
        return ffi.addressof(c) if ffi.typeof(c).kind in ("struct", "union") else c

    def _size(self) -> int:
        ffi = self._ffi
        t = ffi.typeof(self._cdata)
        if t.kind == "pointer":
            return int(ffi.sizeof(t.item))
        return int(ffi.sizeof(self._cdata))

    def copy(self) -> CView:
        """A snapshot: a new view of an independent copy of the memory (later changes not seen).

        A pointer view copies the one item it points to (a ``T *`` of new memory); struct, union and
        array views copy the whole of it. The copy owns its memory and can be written, e.g. saved
        and restored: ``saved = f.state.copy()`` ... ``f.state[0] = saved[0]``.
        """
        ffi = self._ffi
        t = ffi.typeof(self._cdata)
        if t.kind == "array":
            new = ffi.new(ffi.getctype(t.item, "[]"), len(self._cdata))
        elif t.kind == "pointer":
            new = ffi.new(t)
        else:
            new = ffi.new(ffi.getctype(t, "*"))
        ffi.memmove(new, self._source(), self._size())
        view = CView(new, new, ffi)
        return view if t.kind in ("array", "pointer") else view[0]

    def __bytes__(self) -> bytes:
        """The bytes of the viewed memory now (a snapshot; a pointer view: the item it points to)."""
        return bytes(self._ffi.buffer(self._source(), self._size()))

    # --- access -------------------------------------------------------------------------------

    def _wrap(self, value: Any) -> Any:
        ffi = self._ffi
        if not isinstance(value, ffi.CData):
            return value
        sub = _view_class(ffi.typeof(value))
        return value if sub is None else _make(sub, value, self._owner, ffi)

    def __getattr__(self, name: str) -> Any:
        """A field not found among the generated ones (cffi's AttributeError if there is none)."""
        if name in _SLOTS:  # probed before the slots are set (copy, pickle)
            raise AttributeError(name)
        return self._wrap(getattr(self._cdata, name))

    def __setattr__(self, name: str, value: Any) -> None:
        """Write a field of the C memory (a struct field from a CView or cdata of its type)."""
        setattr(self._cdata, name, _unwrap(value))

    def __getitem__(self, index: Any) -> Any:
        """An element (array or pointer views): a number or a CView; a slice is a CView."""
        return self._wrap(self._cdata[index])

    def __setitem__(self, index: Any, value: Any) -> None:
        """Write an element (``view[0] = other[0]`` copies a whole struct)."""
        self._cdata[index] = _unwrap(value)

    def __len__(self) -> int:
        """The number of elements of an array view (TypeError for other views, as in cffi)."""
        return len(self._cdata)

    def __iter__(self) -> Iterator[Any]:
        """The elements of an array view (TypeError for other views, as in cffi)."""
        items = iter(self._cdata)
        return (self._wrap(v) for v in items)

    def __bool__(self) -> bool:
        """False only for a NULL pointer view."""
        return bool(self._cdata != self._ffi.NULL) if self.ctype.kind == "pointer" else True

    def __dir__(self) -> list[str]:
        """The field names of a struct or union (or of the struct a pointer points to)."""
        return sorted(set(_field_names(self.ctype)) | {"ctype", "ptr", "copy"})

    def __copy__(self) -> CView:
        """Another view of the same memory (``copy.copy``); :meth:`copy` is the snapshot."""
        return _make(type(self), self._cdata, self._owner, self._ffi)

    def __deepcopy__(self, memo: dict[int, Any]) -> CView:
        """A snapshot (``copy.deepcopy``): the same as :meth:`copy`."""
        return self.copy()

    def __repr__(self) -> str:
        return f"<attica.CView {self.ctype.cname!r} live>"


_SLOTS = frozenset(CView.__slots__)
_set_cdata = CView._cdata.__set__  # type: ignore[attr-defined]
_set_owner = CView._owner.__set__  # type: ignore[attr-defined]
_set_ffi = CView._ffi.__set__  # type: ignore[attr-defined]
_CLASSES: dict[Any, type[CView] | None] = {}  # ctype -> its view class (None: not viewable)


def _make(cls: type[CView], cdata: Any, owner: Any, ffi: Any) -> CView:
    view: CView = object.__new__(cls)
    _set_cdata(view, cdata)
    _set_owner(view, owner)
    _set_ffi(view, ffi)
    return view


def _field_names(t: Any) -> list[str]:
    if t.kind == "pointer":
        t = t.item
    if t.kind not in ("struct", "union") or not t.fields:
        return []
    return [name for name, _ in t.fields if name]


def _field(name: str) -> property:
    def get(self: CView) -> Any:
        return self._wrap(getattr(self._cdata, name))

    return property(get, doc=f"The C field ``{name}`` (live).")


def _view_class(t: Any) -> type[CView] | None:
    """The CView subclass for ctype ``t`` (None: a ctype that cannot be viewed).

    Its fields are properties: a plain attribute lookup, without the exception ``__getattr__`` costs.
    """
    try:
        return _CLASSES[t]
    except KeyError:
        pass
    sub: type[CView] | None = None
    if t.kind in _AGGREGATE:
        ns: dict[str, Any] = {"__slots__": ()}
        for name in _field_names(t):
            if not hasattr(CView, name):  # the view's own attributes win (docstring)
                ns[name] = _field(name)
        sub = type(f"CView[{t.cname}]", (CView,), ns)
    _CLASSES[t] = sub
    return sub

"""A cheaper ``__init__`` for the frozen, slotted dataclasses built per sample
or per epoch (samples, reports, verdicts).

The ``__init__`` that :func:`dataclasses.dataclass` writes for a frozen class
stores each field with ``object.__setattr__(self, name, value)`` (the class's
own ``__setattr__`` refuses): a global, an attribute and a call per field,
about 70 ns each. With slots, every field has its own slot descriptor, and
its ``__set__`` stores the value directly: the same object, about half the
cost. :func:`fast_frozen_init` writes that ``__init__`` (same parameters, same
defaults, same order) and keeps the generated one as ``__reference_init__``;
``tests/test_fastinit.py`` checks the two build equal objects.

Only plain fields: a class with a ``default_factory``, ``init=False`` fields,
``InitVar`` or ``__post_init__`` is left as it is.
"""

from __future__ import annotations

import dataclasses


def fast_frozen_init(*classes: type) -> None:
    for cls in classes:
        params = cls.__dataclass_params__
        if not (params.frozen and "__slots__" in cls.__dict__) or hasattr(cls, "__post_init__"):
            raise TypeError(f"{cls.__name__}: only frozen, slotted dataclasses without __post_init__")
        fields = dataclasses.fields(cls)
        if any(not f.init or f.default_factory is not dataclasses.MISSING or f.kw_only for f in fields):
            raise TypeError(f"{cls.__name__}: only plain positional fields with plain defaults")
        if len(fields) != len([k for k, v in cls.__annotations__.items()]):
            raise TypeError(f"{cls.__name__}: InitVar or ClassVar fields")
        ns: dict = {}
        args = []
        body = []
        for f in fields:
            ns[f"_set_{f.name}"] = cls.__dict__[f.name].__set__  # the slot descriptor's store
            if f.default is dataclasses.MISSING:
                args.append(f.name)
            else:
                ns[f"_default_{f.name}"] = f.default
                args.append(f"{f.name}=_default_{f.name}")
            body.append(f"    _set_{f.name}(self, {f.name})\n")
        src = f"def __init__(self, {', '.join(args)}):\n{''.join(body)}"
        exec(src, ns)  # noqa: S102 - source built above from the field names only
        init = ns["__init__"]
        init.__qualname__ = f"{cls.__qualname__}.__init__"
        init.__module__ = cls.__module__
        cls.__reference_init__ = cls.__init__
        cls.__init__ = init

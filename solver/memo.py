"""Values computed once per object and kept with it (freed with it), for derived arrays of
a model that several fits reuse: one helper instead of caches keyed on ``id()``."""

import threading

_lock = threading.Lock()


def memo(owner, key, make):
    """``make()`` for ``owner`` and the hashable ``key``, computed on the first call and
    kept in the owner's ``__dict__`` (the owner needs one); thread-safe."""
    store = owner.__dict__.get("_memo")
    if store is None:
        with _lock:
            store = owner.__dict__.setdefault("_memo", {})
    try:
        return store[key]
    except KeyError:
        pass
    value = make()
    with _lock:
        return store.setdefault(key, value)


def memo_items(owner):
    """The (key, value) pairs kept with ``owner`` so far (a snapshot)."""
    with _lock:
        return list(owner.__dict__.get("_memo", {}).items())

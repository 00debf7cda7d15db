"""Plain data (numbers, text, arrays, bytes, and lists, tuples, dicts, deques of them)
as a JSON text and a set of numpy arrays, and back: how a checkpoint keeps dsim's own
state (docs/checkpoints.md).

Written by hand because the field's way, pickle, runs code when it loads, and a
checkpoint is a file a user may be handed; JSON and ``numpy.load(allow_pickle=False)``
only ever build data.  Every float goes through ``repr`` (JSON's text of it reads back
as the same double), every array as its own bytes, so that a run resumed from a
checkpoint continues with the very bits it saved.
"""
from __future__ import annotations

import array
import math
from collections import deque

import numpy as np

#: the tags of what JSON has no word for (a dict whose keys are all other strings
#: is written as a JSON object)
TAGS = ("$array", "$bytes", "$tuple", "$deque", "$dict", "$float", "$typed", "$scalar")


class StateError(ValueError):
    """A value that cannot be kept (encoding), or a text that is not a kept value
    (decoding): the message names where."""


def encode(value, arrays: dict | None = None) -> tuple[object, dict[str, np.ndarray]]:
    """``value`` as a JSON-able tree and the arrays it refers to by key."""
    arrays = {} if arrays is None else arrays
    return _encode(value, arrays, "state"), arrays


def _key(arrays: dict, data: np.ndarray) -> str:
    key = f"a{len(arrays)}"
    arrays[key] = data
    return key


def _encode(value, arrays: dict, where: str):
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, np.generic):  # before float and int: np.float64 is a float
        if value.dtype == object:
            raise StateError(f"{where}: a Python object cannot be kept")
        return {"$scalar": _key(arrays, np.asarray(value))}
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else {"$float": repr(value)}
    if isinstance(value, np.ndarray):
        if value.dtype.hasobject:
            raise StateError(f"{where}: an array of Python objects cannot be kept")
        return {"$array": _key(arrays, value)}
    if isinstance(value, (bytes, bytearray, memoryview)):
        return {"$bytes": _key(arrays, np.frombuffer(bytes(value), dtype=np.uint8))}
    if isinstance(value, array.array):
        return {"$typed": value.typecode, "$array": _key(arrays, np.array(value))}
    if isinstance(value, list):
        return [_encode(item, arrays, f"{where}[{i}]") for i, item in enumerate(value)]
    if isinstance(value, tuple):
        return {"$tuple": [_encode(item, arrays, f"{where}[{i}]")
                           for i, item in enumerate(value)]}
    if isinstance(value, deque):
        return {"$deque": [_encode(item, arrays, f"{where}[{i}]")
                           for i, item in enumerate(value)], "maxlen": value.maxlen}
    if isinstance(value, dict):
        if all(isinstance(k, str) and not k.startswith("$") for k in value):
            return {k: _encode(v, arrays, f"{where}.{k}") for k, v in value.items()}
        return {"$dict": [[_encode(k, arrays, f"{where} key"),
                           _encode(v, arrays, f"{where}[{k!r}]")] for k, v in value.items()]}
    raise StateError(f"{where}: a {type(value).__name__} cannot be kept")


def decode(tree, arrays) -> object:
    """The value :func:`encode` made ``tree`` and ``arrays`` of (``arrays``: a mapping
    of key to array, such as an opened .npz); StateError on anything else."""
    return _decode(tree, arrays, "state")


def _array(arrays, key, where: str) -> np.ndarray:
    if not isinstance(key, str):
        raise StateError(f"{where}: an array key is not a string")
    try:
        return arrays[key]
    except KeyError:
        raise StateError(f"{where}: array '{key}' is missing") from None


def _decode(tree, arrays, where: str):
    if tree is None or isinstance(tree, (bool, str, int, float)):
        return tree
    if isinstance(tree, list):
        return [_decode(item, arrays, f"{where}[{i}]") for i, item in enumerate(tree)]
    if not isinstance(tree, dict):
        raise StateError(f"{where}: a {type(tree).__name__} is no kept value")
    tags = [k for k in tree if k in TAGS]
    if not tags:
        return {k: _decode(v, arrays, f"{where}.{k}") for k, v in tree.items()}
    tag = "$array" if "$typed" in tags else tags[0]
    body = tree[tag]
    if tag == "$array":
        data = np.array(_array(arrays, body, where))
        if "$typed" in tree:
            return array.array(tree["$typed"], data.tolist())
        return data
    if tag == "$scalar":
        data = _array(arrays, body, where)
        return data.dtype.type(data[()])
    if tag == "$bytes":
        return np.asarray(_array(arrays, body, where), dtype=np.uint8).tobytes()
    if tag == "$float":
        if body not in ("nan", "inf", "-inf"):
            raise StateError(f"{where}: '{body}' is no float")
        return float(body)
    if not isinstance(body, list):
        raise StateError(f"{where}: {tag} holds no list")
    items = [_decode(item, arrays, f"{where}[{i}]") for i, item in enumerate(body)]
    if tag == "$tuple":
        return tuple(items)
    if tag == "$deque":
        maxlen = tree.get("maxlen")
        if maxlen is not None and (not isinstance(maxlen, int) or maxlen < 0):
            raise StateError(f"{where}: a deque's maxlen is no count")
        return deque(items, maxlen=maxlen)
    # $dict: pairs
    if not all(isinstance(pair, list) and len(pair) == 2 for pair in items):
        raise StateError(f"{where}: a dict's items are not pairs")
    try:
        return {_hashable(k): v for k, v in items}
    except TypeError:
        raise StateError(f"{where}: a dict key cannot be a key") from None


def _hashable(key):
    return tuple(_hashable(k) for k in key) if isinstance(key, list) else key

"""A batch of demos written as zarr v3 nodes with plain file writes (the zarr store's append path), and read back
the same way (``read_tree``).

Why not ``group.create_array``: zarr-python spends ~3 ms of Python per array (metadata objects, a round trip
through its event loop), concurrent or not, which bounds a demo of ~25 arrays at a few demos/s. Here each
array's ``zarr.json`` is a template that zarr-python itself wrote for the same dtype, rank and codecs (only
``shape`` and ``chunk_shape`` are filled in), and each chunk is that codec chain's output: the C-order
little-endian bytes of the full chunk (edge chunks padded with the fill value, as zarr does), zstd-compressed
by numcodecs as zarr's ``ZstdCodec`` does. Arrays whose template has any other codec chain, and 0-d or empty
arrays, are written by zarr-python. ``read_tree`` reads arrays of that layout from their files (a missing chunk
is the fill value, as zarr leaves chunks out) and hands any other array to zarr-python, whose ~2 ms per array
made a PickCube demo a 50 ms read. ``tests/test_storage.py`` compares both ways with zarr-python's.
"""

from __future__ import annotations

import functools
import json
import math
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import zarr
from numcodecs import Zstd
from zarr.codecs import ZstdCodec
from zarr.storage import LocalStore

from ..files.layout import StoredDemo, demo_name, nest, time_chunks
from ..files.row_pieces import RowPieces
from ..files.write_faults import write_fault_point

IMAGE_ZSTD_LEVEL = 3
"""zstd level of image arrays (frames chunked along time like the other arrays, ~1 MB raw a chunk)."""
STATE_ZSTD_LEVEL = 1
"""zstd level of the other arrays (states, actions, signals): level 1 stores a PickCube demo's arrays in
1.3 % more bytes than zarr's default (level 3) at about half the compression time, the largest CPU share of a
writer process."""


def array_kwargs(value: np.ndarray) -> dict[str, Any]:
    """``create_array`` keywords of a demo array: every array split along time into ~1 MB chunks (``time_chunks``),
    image frames (T, H, W[, 3]) at zstd 3, the rest at zstd 1 (docs/data.md: Image datasets). Chunk files sit in the
    array's folder (``c.<t>.0``).

    Why frames are not one per chunk (as in HDF5, where a chunk is no file): a file per frame made a two-camera
    PickToShelf demo ~800 files, and their creation, not the physics or the render, bound collection with cameras
    (``bench-collect-picktoshelf-cameras``). 50 frames of 96x72 RGB make one chunk; readers keep decoded chunks
    (``zarr.packs.PackReader``), so reading frames in order decodes each chunk once."""
    flat = {"chunk_key_encoding": {"name": "default", "separator": "."}}  # one directory per array, not per chunk row
    level = IMAGE_ZSTD_LEVEL if value.ndim >= 3 else STATE_ZSTD_LEVEL
    return {
        "chunks": chunk_shape(value.shape, value.itemsize) if value.ndim else "auto",
        "compressors": ZstdCodec(level=level),
        **flat,
    }


@functools.lru_cache(maxsize=4096)
def chunk_shape(shape: tuple[int, ...], itemsize: int) -> tuple[int, ...]:
    """Chunk shape of an array of rank >= 1 (see ``array_kwargs``)."""
    return time_chunks(shape, itemsize)


def chunk_grid(shape: tuple[int, ...], chunks: tuple[int, ...]) -> list[int]:
    """Chunks along each axis of an array of ``shape`` cut into ``chunks``."""
    return [math.ceil(s / c) for s, c in zip(shape, chunks)]


@functools.cache
def _template(dtype: str, ndim: int) -> tuple[str, Zstd] | None:
    """(zarr.json text with ``%SHAPE%`` / ``%CHUNKS%`` holes, the chunk compressor) as zarr-python writes an
    array of this dtype and rank; None unless its codec chain is bytes -> zstd with flat ``c.<i>.<j>`` keys."""
    probe = np.zeros((1,) * ndim, dtype=np.dtype(dtype))
    with tempfile.TemporaryDirectory() as tmp:
        zarr.create_array(LocalStore(tmp), data=probe, **array_kwargs(probe))
        meta = json.loads(Path(tmp, "zarr.json").read_text())
    codecs = meta.get("codecs", [])
    if (
        [c.get("name") for c in codecs] != ["bytes", "zstd"]
        or meta.get("attributes")
        or meta.get("chunk_key_encoding", {}).get("name") != "default"
        or meta.get("storage_transformers")
        or meta.get("chunk_grid", {}).get("name") != "regular"
        or meta["chunk_key_encoding"].get("configuration", {}).get("separator") != "."
    ):
        return None
    zstd = codecs[1].get("configuration", {})
    compressor = Zstd(level=int(zstd.get("level", 0)), checksum=bool(zstd.get("checksum", False)))
    meta["shape"], meta["chunk_grid"]["configuration"]["chunk_shape"] = "%SHAPE%", "%CHUNKS%"
    return json.dumps(meta, indent=2), compressor


_CREATE = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_CLOEXEC", 0)


def write_file(path: str, data) -> None:
    """A new file ``path`` holding ``data`` (bytes-like), written with ``os`` calls: no Python file object."""
    write_fault_point()
    fd = os.open(path, _CREATE, 0o666)
    try:
        view = memoryview(data).cast("B")
        while view:
            view = view[os.write(fd, view) :]
    finally:
        os.close(fd)


@functools.lru_cache(maxsize=4096)
def _array_meta(dtype: str, shape: tuple[int, ...]) -> tuple[bytes, Zstd, tuple[int, ...]] | None:
    """(an array's ``zarr.json`` bytes, its chunk compressor, its chunk shape), None where zarr-python writes it:
    the template with its holes filled in, kept per (dtype, shape) because a batch repeats them (its demos share
    lengths and layouts)."""
    template = _template(dtype, len(shape))
    if template is None:
        return None
    text, compressor = template
    chunks = chunk_shape(shape, np.dtype(dtype).itemsize)
    return (
        text.replace('"%SHAPE%"', json.dumps(list(shape))).replace('"%CHUNKS%"', json.dumps(list(chunks))).encode(),
        compressor,
        chunks,
    )


def write_array(node: str, value: np.ndarray, tasks: list[Callable[[], None]] | None = None) -> bool:
    """Write ``value`` as the array ``node`` (a path); False when it needs zarr-python (see the module docstring).
    Plain ``os`` paths and the cached metadata keep the Python per array to a few microseconds: a writer
    process spends most of its ~3 ms per PickCube demo on file creation (about 80 files and folders) and zstd.
    With ``tasks`` the array's folder and ``zarr.json`` are written here and each chunk's encoding and file are
    appended to ``tasks`` as a call (the caller runs them, e.g. on threads: zstd and the writes release the GIL)."""
    if value.ndim == 0 or value.size == 0:
        return False
    found = _array_meta(value.dtype.str, value.shape)
    if found is None:
        return False
    meta, compressor, chunks = found
    os.mkdir(node)
    write_file(f"{node}/zarr.json", meta)
    run = (lambda f, *a: f(*a)) if tasks is None else (lambda f, *a: tasks.append(functools.partial(f, *a)))
    if isinstance(value, RowPieces) and value.dtype.byteorder in "<|=" and chunks[1:] == value.shape[1:]:
        for t in range(chunk_grid(value.shape, chunks)[0]):  # each chunk's rows are gathered where it is encoded
            rows = (t * chunks[0], (t + 1) * chunks[0])
            run(
                _write_rows_chunk,
                f"{node}/c.{'.'.join([str(t)] + ['0'] * (value.ndim - 1))}",
                compressor,
                value,
                rows,
                chunks,
            )
        return True
    value = np.ascontiguousarray(value, dtype=value.dtype.newbyteorder("<"))
    if chunks == value.shape:  # one chunk (most arrays of a demo)
        run(_write_chunk, f"{node}/c.{'.'.join(['0'] * value.ndim)}", compressor, value)
        return True
    for index in np.ndindex(*chunk_grid(value.shape, chunks)):
        block = value[tuple(slice(i * c, (i + 1) * c) for i, c in zip(index, chunks))]
        run(_write_chunk, f"{node}/c.{'.'.join(map(str, index))}", compressor, block, chunks)
    return True


def _write_rows_chunk(
    path: str, compressor: Zstd, value: RowPieces, rows: tuple[int, int], chunks: tuple[int, ...]
) -> None:
    """The chunk of ``value``'s ``rows`` (a time chunk), built from its pieces here."""
    _write_chunk(path, compressor, value.rows(*rows), chunks)


def _write_chunk(path: str, compressor: Zstd, block: np.ndarray, chunks: tuple[int, ...] | None = None) -> None:
    """One chunk file; an edge chunk (smaller than ``chunks``) is stored whole, padded with the fill value (0 /
    false), as zarr stores it."""
    if chunks is not None and block.shape != chunks:
        whole = np.zeros(chunks, block.dtype)
        whole[tuple(slice(0, s) for s in block.shape)] = block
        block = whole
    write_file(path, compressor.encode(np.ascontiguousarray(block)))


def inodes_of(tree: dict[str, Any]) -> int:
    """Files and folders ``write_demo`` makes for the demo ``tree``: two per group (its own included: the folder and
    ``zarr.json``), per array its folder, ``zarr.json`` and chunk files (a PickCube demo: 81)."""
    count = 2
    for value in tree.values():
        if isinstance(value, dict):
            count += inodes_of(value)
            continue
        value = np.asarray(value)
        count += 2
        if value.ndim and value.size:
            count += math.prod(chunk_grid(value.shape, chunk_shape(value.shape, value.itemsize)))
    return count


def write_group(node: str | Path, attrs: dict[str, Any]) -> None:
    """An empty group ``node`` (a new directory) with ``attrs``."""
    os.mkdir(node)
    # no indent: json's C encoder serves only unindented output, and a pack's index holds every demo's attrs
    write_file(f"{node}/zarr.json", json.dumps({"attributes": attrs, "zarr_format": 3, "node_type": "group"}).encode())


def write_demo(
    node: Path, attrs: dict[str, Any], tree: dict[str, Any], fallback: Callable[[str, np.ndarray], None]
) -> None:
    """Demo group ``node`` with ``attrs`` and every array of the nested ``tree``; ``fallback(relpath, value)``
    writes an array this module does not (with zarr-python), after the groups exist. Not durable until the
    caller syncs (one ``syncfs`` per batch). A ``StoredDemo`` tree is copied (``copy_demo``)."""
    if isinstance(tree, StoredDemo):
        copy_demo(node, attrs, tree)
        return
    write_group(node, attrs)
    rest: list[tuple[str, np.ndarray]] = []

    def walk(at: str, sub: dict[str, Any], rel: str) -> None:
        for key, value in sub.items():
            if isinstance(value, dict):
                write_group(f"{at}/{key}", {})
                walk(f"{at}/{key}", value, f"{rel}{key}/")
            elif not write_array(f"{at}/{key}", np.asarray(value)):
                rest.append((f"{rel}{key}", np.asarray(value)))

    walk(os.fspath(node), tree, "")
    for rel, value in rest:
        fallback(rel, value)


def _copy_file(src: str, dst: str) -> None:
    write_fault_point()
    shutil.copyfile(src, dst)


def copy_demo(node: str | Path, attrs: dict[str, Any], src: StoredDemo) -> None:
    """Demo group ``node`` as a file copy of the committed demo ``src`` (same layout, same codecs: nothing is
    decoded), its attrs the source's updated with ``attrs``."""
    shutil.copytree(src.path / "data" / demo_name(src.demo_id), node, copy_function=_copy_file)
    meta = json.loads(Path(node, "zarr.json").read_bytes())
    meta["attributes"] = {**meta.get("attributes", {}), **attrs}
    write_file(f"{node}/zarr.json", json.dumps(meta, indent=2).encode())


_PLAIN_DTYPES = {
    "bool",
    "int8",
    "int16",
    "int32",
    "int64",
    "uint8",
    "uint16",
    "uint32",
    "uint64",
    "float16",
    "float32",
    "float64",
}
DECODER = Zstd()


def node_meta(node: str) -> dict[str, Any] | None:
    """A node's parsed ``zarr.json`` (None: not a node)."""
    try:
        with open(f"{node}/zarr.json", "rb") as f:
            return json.loads(f.read())
    except (FileNotFoundError, NotADirectoryError):
        return None


def plain_dtype(meta: dict[str, Any]) -> np.dtype | None:
    """The dtype of an array stored as ``write_array`` stores it (regular grid, ``c.<i>.<j>`` keys, little-endian
    bytes -> zstd, a numeric fill value, rank >= 1); None for any other array."""
    codecs = meta.get("codecs", [])
    key = meta.get("chunk_key_encoding", {})
    if (
        meta.get("data_type") not in _PLAIN_DTYPES
        or not meta.get("shape")
        or 0 in meta["shape"]
        or meta.get("storage_transformers")
        or meta.get("chunk_grid", {}).get("name") != "regular"
        or key.get("name") != "default"
        or key.get("configuration", {}).get("separator") != "."
        or [c.get("name") for c in codecs] != ["bytes", "zstd"]
        or (codecs[0].get("configuration") or {}).get("endian", "little") != "little"
        or not isinstance(meta.get("fill_value"), (bool, int, float))
    ):
        return None
    return np.dtype(meta["data_type"]).newbyteorder("<")


def read_array(node: str, meta: dict[str, Any]) -> np.ndarray | None:
    """The array ``node`` (its parsed ``zarr.json`` is ``meta``) read from its chunk files; None when its layout is
    not the plain one (``plain_dtype``)."""
    dtype = plain_dtype(meta)
    if dtype is None:
        return None
    shape, chunks = tuple(meta["shape"]), tuple(meta["chunk_grid"]["configuration"]["chunk_shape"])
    out = np.empty(shape, dtype) if chunks == shape else np.full(shape, meta["fill_value"], dtype)
    for index in np.ndindex(*[math.ceil(s / c) for s, c in zip(shape, chunks)]):
        try:
            with open(f"{node}/c.{'.'.join(map(str, index))}", "rb") as f:
                raw = f.read()
        except FileNotFoundError:  # zarr leaves out a chunk that holds only the fill value
            if chunks == shape:
                out.fill(meta["fill_value"])
            continue
        block = np.frombuffer(DECODER.decode(raw), dtype).reshape(chunks)
        at = tuple(slice(i * c, min((i + 1) * c, s)) for i, c, s in zip(index, chunks, shape))
        out[at] = block[tuple(slice(0, a.stop - a.start) for a in at)]
    return out


def read_tree(node: str | Path, keys: tuple[str, ...] | None, fallback: Callable[[str], np.ndarray]) -> dict[str, Any]:
    """Every array under the group ``node`` nested as stored (sorted), or only those named by ``keys``
    ("actions", "obs/front_head_rgb"; a key that is not an array is left out); ``fallback(relpath)`` reads an array
    ``read_array`` does not (with zarr-python)."""
    node = os.fspath(node)

    def array(rel: str, meta: dict[str, Any]) -> np.ndarray:
        value = read_array(f"{node}/{rel}", meta)
        return fallback(rel) if value is None else value

    def walk(rel: str) -> dict[str, Any]:
        tree = {}
        for name in sorted(os.listdir(f"{node}/{rel}")):
            meta = node_meta(f"{node}/{rel}{name}")
            if meta is not None and meta.get("node_type") == "group":
                tree[name] = walk(f"{rel}{name}/")
            elif meta is not None and meta.get("node_type") == "array":
                tree[name] = array(f"{rel}{name}", meta)
        return tree

    if keys is None:
        return walk("")
    metas = {k: node_meta(f"{node}/{k}") for k in keys}
    return nest({k: array(k, m) for k, m in metas.items() if m is not None and m.get("node_type") == "array"})

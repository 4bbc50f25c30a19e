"""Faces of any size to quads, by the one rule every mesh reader uses (``non_quads``).

The OBJ, OFF, PLY and .3dm readers all end with a list of polygons; a face with
four corners is a panel, any other face is refused, dropped or split exactly as
:func:`quadnodes.io.obj.parse_obj` does it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .. import _validate
from ..errors import InputError

__all__ = ["NON_QUAD_OPTIONS", "quads_from_blocks"]

NON_QUAD_OPTIONS: tuple[str, ...] = ("error", "drop", "split")
"""The values of ``non_quads`` in every mesh reader."""

_ADVICE = "only quads are supported (non_quads='drop' skips such faces, 'split' splits even polygons)"


def quads_from_blocks(
    blocks: Sequence[tuple[np.ndarray, np.ndarray]],
    *,
    non_quads: str = "error",
    name: str = "<mesh>",
    what: str = "face",
) -> np.ndarray:
    """Quads from polygon blocks, in file order.

    Parameters
    ----------
    blocks : sequence of (corners, positions)
        ``corners`` ``(c, k) int`` holds ``c`` faces of ``k`` corners each;
        ``positions`` ``(c,) int`` their places in the file (face numbers), used
        for the order of the result and in messages.
    non_quads : {"error", "drop", "split"}
        As in :func:`quadnodes.io.obj.parse_obj`: refuse, skip, or split an even
        polygon (``k >= 6``) into the fan of ``k/2 - 1`` quads.
    name : str
        The source in messages (a file name).
    what : str
        What a position is called in messages (``"face"``).

    Returns
    -------
    (m, 4) int64

    Raises
    ------
    InputError
        Naming the first face at fault and its number of corners.

    Examples
    --------
    >>> quads_from_blocks([(np.array([[0, 1, 2, 3]]), np.array([0]))]).tolist()
    [[0, 1, 2, 3]]
    >>> quads_from_blocks([(np.array([[0, 1, 2]]), np.array([5]))], name="t.off")
    Traceback (most recent call last):
      ...
    quadnodes.errors.InputError: t.off: face 5 has 3 corners; only quads are supported (non_quads='drop' skips such faces, 'split' splits even polygons)
    """
    mode = _validate.choice(non_quads, NON_QUAD_OPTIONS, "non_quads")
    quads: list[np.ndarray] = []
    keys: list[np.ndarray] = []
    for corners, positions in blocks:
        corners = np.asarray(corners, dtype=np.int64)
        positions = np.asarray(positions, dtype=np.int64)
        if corners.size == 0:
            continue
        k = corners.shape[1]
        if k == 4:
            quads.append(corners)
            keys.append(positions.astype(np.float64))
            continue
        first = int(positions.min())
        if k < 3:
            raise InputError(f"{name}: {what} {first} has {k} corners; a face needs at least 3")
        if mode == "drop":
            continue
        if mode == "split" and k % 2 == 0:
            n_split = k // 2 - 1
            s = 2 * np.arange(n_split) + 1
            fan = np.stack(
                [np.broadcast_to(corners[:, :1], (len(corners), n_split)), corners[:, s], corners[:, s + 1], corners[:, s + 2]],
                axis=2,
            )
            quads.append(fan.reshape(-1, 4))
            keys.append((positions[:, None] + np.arange(n_split) / n_split).reshape(-1))
            continue
        extra = "an odd polygon cannot be split into quads without new vertices" if mode == "split" else _ADVICE
        raise InputError(f"{name}: {what} {first} has {k} corners; {extra}")
    if not quads:
        return np.zeros((0, 4), dtype=np.int64)
    faces = np.concatenate(quads)
    order = np.argsort(np.concatenate(keys), kind="stable")
    return faces[order]

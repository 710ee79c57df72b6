"""refexmc.campaign.shared_arrays: the GPU backend's launch arrays, which its host workers write and read.

What must hold: another process attached by the handle sees and writes the same memory; its exit
does not free the block, the owner's release does (no process can attach any more), and a
descriptor number reused by another file is not taken for the block; and a part a worker wrote to
the work directory is renamed into place (``storage.place_part``).
"""

import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from refexmc.campaign import shared_arrays, storage

ROOT = Path(__file__).resolve().parents[1]
needs_shared_memory = pytest.mark.skipif(not shared_arrays.shareable(), reason="no memory files (not Linux)")

_CHILD = """
import pickle, sys
import numpy as np
from refexmc.campaign import shared_arrays
handle = pickle.loads(bytes.fromhex(sys.argv[1]))
try:
    with shared_arrays.attached(handle) as arrays:
        print(float(arrays["inputs"][2, 1]), arrays["empty"].shape, arrays["counts"].tolist())
        arrays["counts"][:] = np.arange(3) + 7
except FileNotFoundError as exc:
    print("gone:", exc)
"""


def _attach_in_a_child(handle):
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, pickle.dumps(handle).hex()],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONWARNINGS": "error::UserWarning"},
    )
    assert done.returncode == 0 and not done.stderr.strip(), done.stderr
    return done.stdout.strip()


@needs_shared_memory
def test_a_process_attached_by_the_handle_shares_the_block_until_the_owner_releases_it(tmp_path):
    shapes = {"inputs": ((3, 4), np.float64), "empty": ((3, 0, 1, 4), np.float64), "counts": ((3,), np.int64)}
    block = shared_arrays.Arrays(shapes, shared=True)
    try:
        assert not block["inputs"].any() and not block["counts"].any()  # zeroed
        block["inputs"][2, 1] = 2.5
        handle = block.handle()
        assert _attach_in_a_child(handle) == "2.5 (3, 0, 1, 4) [0, 0, 0]"
        assert block["counts"].tolist() == [7, 8, 9]  # what the child wrote
        assert _attach_in_a_child(handle) == "2.5 (3, 0, 1, 4) [7, 8, 9]"  # the first child's exit freed nothing
        assert block["empty"].strides == np.zeros((3, 0, 1, 4)).strides  # numpy's own, as a device array's
    finally:
        block.release()
    assert _attach_in_a_child(handle).startswith("gone:")  # released: no process can attach
    number = int(handle.path.rsplit("/", 1)[1])
    other = os.open(tmp_path / "other", os.O_RDWR | os.O_CREAT)  # a file given the block's descriptor number
    if other != number:
        os.dup2(other, number)
        os.close(other)
    try:
        assert _attach_in_a_child(handle).startswith("gone:")  # not taken for the block
    finally:
        os.close(number)
    assert os.path.getsize(tmp_path / "other") == 0


def test_private_arrays_are_zeroed_and_have_no_handle_to_attach_by():
    block = shared_arrays.Arrays({"a": ((2, 3), np.float64), "b": ((4,), np.int64)}, shared=False)
    assert block.handle().path is None
    with shared_arrays.attached(block) as arrays:
        assert arrays["a"].shape == (2, 3) and not arrays["a"].any() and arrays["b"].dtype == np.int64
    block.release()


def test_a_part_a_worker_wrote_is_renamed_into_place_and_bytes_are_written(tmp_path):
    written = tmp_path / ".work" / "gpu-runs-part-00003.parquet"
    written.parent.mkdir()
    written.write_bytes(b"runs part")
    storage.place_part(written, tmp_path / "runs" / "part-00003.parquet")
    storage.place_part(b"history part", tmp_path / "histories" / "part-00003.parquet")
    assert not written.exists()
    assert (tmp_path / "runs" / "part-00003.parquet").read_bytes() == b"runs part"
    assert (tmp_path / "histories" / "part-00003.parquet").read_bytes() == b"history part"
    with pytest.raises(OSError, match="part-00004"):  # names the part it could not place
        storage.place_part(written, tmp_path / "runs" / "part-00004.parquet")

"""viscd.DistributedDetector over mpi4py, run under mpirun (ctest: mpi.python with 1 and 3 ranks).

Every rank builds the same scene; each takes the objects of its slab; rank 0 compares the gathered
pairs with viscd.Detector('reference'), a brute force over every object. Every test is collective:
an assertion that fails on one rank only fails after the collective calls it shares with the others.
"""
import numpy as np
import pytest
from mpi4py import MPI

import viscd

comm = MPI.COMM_WORLD
rank, size = comm.Get_rank(), comm.Get_size()


def scene(n, seed, boxes=False):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(0, 100, (n, 3)).astype(np.float32)
    radii = rng.uniform(0.5, 3.0, n).astype(np.float32)
    ids = (np.uint64(1) << np.uint64(40)) + rng.permutation(n).astype(np.uint64) * np.uint64(3)
    owner = np.minimum((centres[:, 0] / 100 * size).astype(int), size - 1)
    if boxes:
        shapes = np.hstack([centres - radii[:, None], centres + radii[:, None]]).astype(np.float32)
    else:
        shapes = np.hstack([centres, radii[:, None]]).astype(np.float32)
    return shapes, ids, owner


def oracle(shapes, ids, boxes=False, filters=None, static=None, static_ids=None):
    det = viscd.Detector("reference")
    if static is not None:
        det.set_static(**({"boxes": static} if boxes else {"spheres": static}))
    frame = det.detect(**({"boxes": shapes} if boxes else {"spheres": shapes}), filters=filters)
    a = ids[frame.pairs[:, 0]]
    is_static = viscd.is_static(frame.pairs[:, 1])
    b = np.empty_like(a)
    b[~is_static] = ids[frame.pairs[~is_static, 1]]
    if static_ids is not None:
        b[is_static] = static_ids[viscd.static_slot(frame.pairs[is_static, 1])]
    pairs = np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))
    return pairs[order], frame.state


@pytest.mark.parametrize("boxes", [False, True])
def test_gathered_pairs_equal_the_brute_force(boxes):
    shapes, ids, owner = scene(1200, 5, boxes)
    mine = owner == rank
    det = viscd.DistributedDetector(comm)
    assert (det.rank, det.size) == (rank, size)
    frame = det.detect(**({"boxes": shapes[mine]} if boxes else {"spheres": shapes[mine]}), ids=ids[mine])
    all_pairs = det.gather_pairs(frame)
    expected, state = oracle(shapes, ids, boxes)
    assert frame.pairs.dtype == np.uint64 and frame.pairs.shape[1] == 2
    assert np.array_equal(frame.state, state[mine])
    assert frame.stats["objects"] == int(mine.sum())
    if rank == 0:
        assert np.array_equal(all_pairs, expected)
    else:
        assert all_pairs is None
    assert comm.allreduce(len(frame.pairs)) == len(expected)


def test_filters_and_a_static_set_per_rank():
    shapes, ids, owner = scene(900, 6)
    rng = np.random.default_rng(7)
    filters = np.stack([1 << rng.integers(0, 3, 900), 0xFFFFFFFF ^ (1 << rng.integers(0, 3, 900))], axis=1).astype(np.uint32)
    static, _, static_owner = scene(120, 8)
    static_ids = np.arange(120, dtype=np.uint64)  # another id range than the moving objects'
    det = viscd.DistributedDetector(comm)
    det.set_static(spheres=static[static_owner == rank], ids=static_ids[static_owner == rank])
    mine = owner == rank
    frame = det.detect(spheres=shapes[mine], ids=ids[mine], filters=filters[mine])
    all_pairs = det.gather_pairs(frame)
    expected, _ = oracle(shapes, ids, filters=filters, static=static, static_ids=static_ids)
    if rank == 0:
        assert np.array_equal(all_pairs, expected)


def test_bad_input_on_one_rank_raises_the_same_error_everywhere():
    shapes, ids, owner = scene(300, 9)
    mine = owner == rank
    spheres = shapes[mine].copy()
    if rank == size - 1:
        spheres = np.vstack([spheres, [[np.nan, 0, 0, 1]]]).astype(np.float32)
    det = viscd.DistributedDetector(comm)
    my_ids = ids[mine] if rank != size - 1 else np.append(ids[mine], np.uint64(1))
    with pytest.raises(ValueError) as info:
        det.detect(spheres=spheres, ids=my_ids)
    messages = comm.allgather(str(info.value))
    assert len(set(messages)) == 1 and messages[0].startswith(f"rank {size - 1}: sphere")
    # The detector still runs afterwards.
    frame = det.detect(spheres=shapes[mine], ids=ids[mine])
    assert comm.allreduce(len(frame.pairs)) == len(oracle(shapes, ids)[0])


def test_argument_errors_are_local_and_clear():
    det = viscd.DistributedDetector(comm)
    with pytest.raises(ValueError, match="ids"):
        det.set_static(spheres=np.zeros((2, 4), np.float32), ids=[1])
    with pytest.raises(ValueError, match="negative"):
        det.set_static(spheres=np.zeros((1, 4), np.float32), ids=[-1])
    with pytest.raises(ValueError, match="integers"):
        det.set_static(spheres=np.zeros((1, 4), np.float32), ids=[1.5])


def test_a_call_during_another_threads_frame_raises():
    """Calls are collective and must come from one thread: a second thread's call raises instead of
    interleaving MPI calls. (clear_static is local, so polling with it is safe on any rank.)"""
    import threading

    shapes, ids, owner = scene(300_000, 10)
    mine = owner == rank
    det = viscd.DistributedDetector(comm, threads=1)
    worker = threading.Thread(target=lambda: det.detect(spheres=shapes[mine], ids=ids[mine]))
    refused = 0
    worker.start()
    while worker.is_alive():
        try:
            det.clear_static()
        except RuntimeError as e:
            assert "another thread" in str(e)
            refused += 1
    worker.join()
    assert refused > 0, "no call ever met the running frame"

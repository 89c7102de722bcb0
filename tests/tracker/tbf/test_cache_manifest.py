"""A set's manifest vouches for every file added to its folder and every derived value, and keeps the additions of
parallel processes."""

import json
import multiprocessing

import pytest

from tracker.tbf import cache_manifest


@pytest.fixture
def folder(tmp_path):
    folder = tmp_path / "set"
    folder.mkdir()
    cache_manifest.write(folder, {"key": "set", "arrays": {}})
    return folder


def test_an_added_file_is_vouched_for_until_a_byte_changes(folder):
    assert cache_manifest.checked_file(folder, "tree-a.npz") is None  # neither the file nor its entry
    (folder / "tree-a.npz").write_bytes(b"0123456789")
    with pytest.raises(ValueError, match="not in the set's manifest"):
        cache_manifest.checked_file(folder, "tree-a.npz")
    cache_manifest.add_file(folder, "tree-a.npz")
    assert cache_manifest.checked_file(folder, "tree-a.npz") == folder / "tree-a.npz"
    (folder / "tree-a.npz").write_bytes(b"0123456780")  # same size, one byte changed
    with pytest.raises(ValueError, match="does not match its checksum"):
        cache_manifest.checked_file(folder, "tree-a.npz")
    (folder / "tree-a.npz").unlink()
    with pytest.raises(ValueError, match="is missing"):
        cache_manifest.checked_file(folder, "tree-a.npz")


def test_derived_values_edited_by_hand_are_not_used(folder, caplog):
    cache_manifest.add_derived(folder, "sigma", 0.25)
    cache_manifest.add_derived(folder, "share", 0.5)
    assert cache_manifest.derived_values(folder) == {"sigma": 0.25, "share": 0.5}
    manifest = json.loads((folder / "meta.json").read_text())
    manifest["derived"]["values"]["sigma"] = 250.0
    (folder / "meta.json").write_text(json.dumps(manifest))
    assert cache_manifest.derived_values(folder) == {} and "do not match their digest" in caplog.text
    cache_manifest.add_derived(folder, "sigma", 0.25)  # computed again: the damaged ones are not carried over
    assert cache_manifest.derived_values(folder) == {"sigma": 0.25}


def _add_values(folder, prefix: str, together) -> None:
    together.wait()  # both start adding at once
    for k in range(VALUES):
        cache_manifest.add_derived(folder, f"{prefix}{k}", float(k))


VALUES = 100  # per process (without the manifest's lock, some are lost: 19 of 200 in one try)


def test_two_processes_adding_at_once_keep_each_others_entries(folder):
    context = multiprocessing.get_context("spawn")
    together = context.Barrier(2)
    workers = [context.Process(target=_add_values, args=(folder, prefix, together)) for prefix in "ab"]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(timeout=60)
    assert [worker.exitcode for worker in workers] == [0, 0]
    assert len(cache_manifest.derived_values(folder)) == 2 * VALUES

"""A dataset's manifest may only point at files inside the dataset folder."""

import json
import os
from dataclasses import asdict

import pytest

from dancesynth.core.errors import DancesynthError
from stage1_pose.data.layout import MANIFEST, Clip, clip_paths, create_layout, read_manifest, write_manifest


def _dataset(root, **changes):
    """A one-clip dataset whose clip entry has ``changes`` applied; its files exist in the standard layout."""
    create_layout(root)
    paths = clip_paths("clip0")
    for rel in paths.values():
        (root / rel).write_bytes(b"x")
    clip = Clip(**{**dict(id="clip0", song="s", style="hiphop", split="train", **paths), **changes})
    write_manifest(root, 15, 22050, ["hiphop"], [clip])
    return root


def test_a_standard_dataset_and_links_within_it_are_accepted(tmp_path):
    root = _dataset(tmp_path / "data")
    (root / "audio" / "again.wav").symlink_to(root / "audio" / "clip0.wav")
    write_manifest(root, 15, 22050, ["hiphop"], [Clip("clip-0.v2", "s", "hiphop", "train",
                                                      "audio/again.wav", "poses/clip0.npz", "./beats/clip0.json")])
    assert [c.id for c in read_manifest(root).clips] == ["clip-0.v2"]


@pytest.mark.parametrize("key, value", [("audio", "../in/song.wav"), ("poses", "audio/../../poses.npz"),
                                        ("beats", "ABSOLUTE")])
def test_paths_leading_out_of_the_dataset_are_refused_naming_the_clip(tmp_path, key, value):
    outside = tmp_path / "in" / "song.wav"
    outside.parent.mkdir()
    outside.write_bytes(b"x")
    root = _dataset(tmp_path / "data", **{key: str(outside) if value == "ABSOLUTE" else value})
    with pytest.raises(DancesynthError, match=f"Clip 'clip0' .* {key} .*outside the dataset folder"):
        read_manifest(root)


def test_a_link_to_a_file_outside_the_dataset_is_refused(tmp_path):
    secret = tmp_path / "secret.wav"
    secret.write_bytes(b"x")
    root = _dataset(tmp_path / "data")
    os.remove(root / "audio" / "clip0.wav")
    (root / "audio" / "clip0.wav").symlink_to(secret)
    with pytest.raises(DancesynthError, match="Clip 'clip0' .*audio.*outside the dataset folder"):
        read_manifest(root)


def test_a_linked_feature_cache_outside_the_dataset_is_refused(tmp_path):
    root = _dataset(tmp_path / "data")
    (tmp_path / "elsewhere").mkdir()
    (root / "features").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(DancesynthError, match="features links outside the dataset"):
        read_manifest(root)


@pytest.mark.parametrize("clip_id", ["../../../X", "a/b", "..", "", "x\\y", "clip\n0"])
def test_clip_ids_that_are_not_plain_names_are_refused(tmp_path, clip_id):
    root = _dataset(tmp_path / "data")
    manifest = json.loads((root / MANIFEST).read_text())
    manifest["clips"][0]["id"] = clip_id
    (root / MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(DancesynthError, match="is not a plain name") as info:
        read_manifest(root)
    assert repr(clip_id) in str(info.value)


def test_the_dataset_folder_may_itself_be_a_link(tmp_path):
    root = _dataset(tmp_path / "data")
    (tmp_path / "link").symlink_to(root)
    assert [asdict(c)["id"] for c in read_manifest(tmp_path / "link").clips] == ["clip0"]


def test_a_file_given_as_the_dataset_folder_is_named_as_a_file(tmp_path):
    (tmp_path / "data.zip").write_bytes(b"PK")
    with pytest.raises(DancesynthError, match="is a file, not a dataset folder"):
        read_manifest(tmp_path / "data.zip")

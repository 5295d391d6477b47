"""Atomic output: a failed write leaves nothing behind; a good one replaces the target."""
import os

import pytest

from linkfea.files.atomic import atomic_path, write_text


def test_failed_write_leaves_no_file(tmp_path):
    target = tmp_path / "sub" / "result.json"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            with open(tmp, "w") as fh:
                fh.write("partial")
            raise RuntimeError("writer failed half way")
    assert not target.exists()
    assert os.listdir(target.parent) == []


def test_write_replaces_and_creates_parent(tmp_path):
    target = tmp_path / "a" / "b.txt"
    write_text(target, "one")
    write_text(target, "two")
    assert target.read_text() == "two"
    assert os.listdir(target.parent) == ["b.txt"]

"""A broken mesh-cache entry is reported by the file that is broken (issue 35, row 19): garbage in
``<key>.json`` was reported as "<key>.msh unreadable"."""
import logging

import pytest

from millimpact.geometry.mesh import _load_cached


@pytest.mark.parametrize("text", ["garbage {", "[1, 2]", '{"params": {"a": 1}}', ""])
def test_garbage_metadata_is_named_as_such(text, tmp_path, caplog):
    (tmp_path / "k.msh").write_text("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n")
    (tmp_path / "k.json").write_text(text)
    with caplog.at_level(logging.WARNING, logger="millimpact.geometry.mesh"):
        assert _load_cached(tmp_path, "k", {"a": 1}) is None
    (record,) = [r for r in caplog.records if r.levelno == logging.WARNING]
    message = record.getMessage()
    assert "its metadata k.json is unreadable" in message and "k.msh" not in message

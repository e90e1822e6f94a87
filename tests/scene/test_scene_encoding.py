"""A scene TOML saved by a Windows editor (issue 35, row 14): a UTF-8 byte-order mark is read, a
Latin-1 file is refused in one line naming the byte (TOML files are UTF-8)."""
from conftest import run_cli
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.toml_io import dump_scene, load_scene


def test_a_utf8_bom_is_read(tmp_path):
    text = dump_scene(builtin_scene("paper-rig")).replace('description = "', 'description = "Café ')
    f = tmp_path / "bom.toml"
    f.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    scene = load_scene(f)
    assert scene.description.startswith("Café ") and scene.ball == builtin_scene("paper-rig").ball


def test_a_latin1_scene_is_one_line_naming_the_byte(tmp_path):
    text = dump_scene(builtin_scene("paper-rig")).replace('description = "', 'description = "Café ')
    f = tmp_path / "latin1.toml"
    f.write_bytes(text.encode("latin-1"))
    line_no = next(i for i, line in enumerate(text.splitlines(), 1) if "Café" in line)
    r = run_cli("hertz", str(f))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "is not UTF-8 text (byte 0xe9 at line " + str(line_no) in lines[0]

"""The command kit (millimpact/commandkit/): one reading of ``--set`` for every command, and the
keyed store of finished pieces.

The ``--set`` pair below only holds when applied together: ``impact.gap`` must stay at most
``ball.radius`` (scene/schema.py), and the gap 0.07 m is more than liner-segment's ball radius
0.0625 m, so applying the gap first, alone, is refused. Every command that takes ``--set`` is
parsed by the real command line and asked for the scene it would compute (its ``command_scene``:
before any mesh, Yade run or output folder), and must accept the pair in either order and give the
same scene as the scene's own ``with_values``.
"""
from __future__ import annotations

import hashlib
import json

import pytest

from millimpact import cli
from millimpact.commandkit.settings import apply_sets, parse_options
from millimpact.commandkit.store import PieceStore, kept_note, piece_key, write_atomic
from millimpact.errors import InputError, SceneError
from millimpact.scene.builtin import resolve_scene
from millimpact.scene.toml_io import dump_scene

SCENE = "liner-segment"
PAIR = ["--set", "impact.gap=0.07", "--set", "ball.radius=0.08"]
SWAPPED = PAIR[2:] + PAIR[:2]

#: each command's arguments before the --set pair (all it needs to reach its scene)
COMMANDS = {
    "run": ["run", SCENE],
    "mesh": ["mesh", SCENE],
    "study": ["study", "--param", "impact.velocity=4,5", "--base", SCENE],
    "table": ["table", SCENE, "--velocity", "4"],
    "repeat": ["repeat", SCENE, "--impacts", "2", "--out", "unused"],
    "mill": ["mill", SCENE, "--revolutions", "1"],
    "damage": ["damage", SCENE, "--impacts", "unused.csv"],
}


def _accepted(argv: list[str]):
    args = cli.build_parser().parse_args(argv)
    seam = cli.command_scene if args.command in ("run", "mesh") else cli._command_module(args.command).command_scene
    return seam(args)


def test_the_pair_is_refused_one_at_a_time():
    """The pair is a real test of order: the gap alone, first, is out of range."""
    with pytest.raises(SceneError, match="impact.gap"):
        resolve_scene(SCENE).with_value("impact.gap", 0.07)


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("pair", [PAIR, SWAPPED], ids=["gap-first", "radius-first"])
def test_every_command_accepts_the_same_scene(command, pair):
    expected = resolve_scene(SCENE).with_values([("impact.gap", 0.07), ("ball.radius", 0.08)])
    scene = _accepted(COMMANDS[command] + pair)
    assert (scene.impact.gap, scene.ball.radius) == (0.07, 0.08)
    assert dump_scene(scene) == dump_scene(expected)


@pytest.mark.parametrize("command", ["table", "damage"])
def test_a_field_the_command_sets_itself_is_refused(command):
    with pytest.raises(InputError, match="--set impact.velocity: conflicts with"):
        _accepted(COMMANDS[command] + ["--set", "impact.velocity=[0, -3, 0]"])


@pytest.mark.parametrize("flag, item", [("--set", "ball.radius"), ("--set", "=0.02"), ("--set", "ball.radius=")])
def test_a_malformed_set_is_one_line(flag, item):
    with pytest.raises(InputError, match="expected FIELD=VALUE"):
        apply_sets(resolve_scene(SCENE), [item])


def test_options_are_typed_and_a_later_key_wins():
    assert parse_options(["modes=20", "integrator=newmark", "modes=30"]) == {"modes": 30, "integrator": "newmark"}
    assert parse_options([]) == {}
    with pytest.raises(InputError, match="expected KEY=VALUE"):
        parse_options(["modes"])


def test_piece_key_is_the_stored_pieces_key():
    """The key of the pieces already on disk: SHA-1 of the sorted JSON, 16 hex digits (written
    out here, so a change of the key that would orphan stored tables and maps fails)."""
    what = {"scene": "[ball]\nradius = 0.02\n", "method": "improved", "options": [("modes", 20)], "version": "0.1.0"}
    text = '{"method": "improved", "options": [["modes", 20]], "scene": "[ball]\\nradius = 0.02\\n", "version": "0.1.0"}'
    assert piece_key(what) == hashlib.sha1(text.encode()).hexdigest()[:16]
    assert piece_key({**what, "method": "full"}) != piece_key(what)


def test_store_saves_loads_and_refuses_a_broken_piece(tmp_path):
    store = PieceStore(tmp_path / "cases")
    assert store.load("abc") is None and store.count() == 0
    store.save("abc", {"e_n": 0.5})
    assert store.load("abc") == {"e_n": 0.5} and store.count() == 1
    assert [p.name for p in (tmp_path / "cases").iterdir()] == ["abc.json"]   # no temporary left
    (tmp_path / "cases" / "bad.json").write_text('{"e_n": 0.')                 # not JSON: computed again
    assert store.load("bad") is None


def test_an_interrupted_write_leaves_the_old_file(tmp_path):
    path = tmp_path / "summary.json"
    path.write_text(json.dumps({"old": 1}))

    def fails(tmp):
        tmp.write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomic(path, fails)
    assert json.loads(path.read_text()) == {"old": 1} and [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_kept_note():
    note = kept_note([(3, "bin", "out/d/cases/"), (1, "repeated-impact sequence", "out/d/repeat/")],
                     "the map itself is not written")
    assert note == ("3 finished bin(s) kept in out/d/cases/ and 1 finished repeated-impact sequence(s) in "
                    "out/d/repeat/ (the map itself is not written); the same command, run again, continues from them")

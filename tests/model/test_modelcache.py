import os
import subprocess
import sys
import textwrap

import mujoco
import numpy as np
import pytest

from so101sim.model import cache as modelcache
from so101sim.model import scene_path
from so101sim.model.build import compile_spec
from so101sim.motion import LAB_MOTION, run_segments
from so101sim.sim.simulation import Simulation


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("SO101SIM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("SO101SIM_NO_CACHE", raising=False)
    return tmp_path / "cache"


def _compile():
    return mujoco.MjModel.from_xml_path(str(scene_path()))


def test_a_cached_model_runs_the_lab_motion_bit_for_bit(cache):
    first = modelcache.load_or_compile(scene_path(), _compile)
    assert modelcache.info().entries == 1
    second = modelcache.load_or_compile(scene_path(), lambda: pytest.fail("compiled again"))
    traces = []
    for m in (_compile(), first, second):
        sim = Simulation(m)
        r = run_segments(sim, LAB_MOTION, trace=True)
        traces.append(np.vstack([s.measured for s in r.segments]))
    np.testing.assert_array_equal(traces[0], traces[1])
    np.testing.assert_array_equal(traces[0], traces[2])


def test_a_changed_file_or_mujoco_version_is_another_entry(cache, tmp_path, monkeypatch):
    from so101sim.model import model_dir

    copy = tmp_path / "model"
    copy.mkdir()
    for f in model_dir().iterdir():
        if f.is_file():
            (copy / f.name).write_bytes(f.read_bytes())
    (copy / "assets").symlink_to(model_dir() / "assets")
    k1 = modelcache.key_for(copy / "scene.xml")
    (copy / "scene.xml").write_text((copy / "scene.xml").read_text() + "\n<!-- edited -->\n")
    assert modelcache.key_for(copy / "scene.xml") != k1
    k2 = modelcache.key_for(copy / "scene.xml")
    monkeypatch.setattr(mujoco, "__version__", "0.0.0")
    assert modelcache.key_for(copy / "scene.xml") != k2
    assert modelcache.key_for(copy / "scene.xml", "draft") != modelcache.key_for(copy / "scene.xml")


def test_a_broken_entry_is_replaced_and_an_unwritable_cache_falls_back(cache, tmp_path):
    modelcache.load_or_compile(scene_path(), _compile)
    entry = next(cache.glob("*.mjb"))
    entry.write_bytes(b"not a model")
    m = modelcache.load_or_compile(scene_path(), _compile)
    assert m.nq == _compile().nq and entry.stat().st_size > 1000
    entry.with_name(entry.name + modelcache.DIGEST_SUFFIX).unlink()  # an entry without its digest
    assert modelcache.load_or_compile(scene_path(), _compile).nq == m.nq
    blocker = tmp_path / "file"
    blocker.write_text("x")
    os.environ["SO101SIM_CACHE_DIR"] = str(blocker / "sub")  # a folder that cannot be made
    assert modelcache.load_or_compile(scene_path(), _compile).nq == m.nq
    assert modelcache.clear().entries == 0  # nothing there, nothing to delete


def test_the_cache_can_be_turned_off_and_cleared(cache, monkeypatch):
    monkeypatch.setenv("SO101SIM_NO_CACHE", "1")
    modelcache.load_or_compile(scene_path(), _compile)
    assert modelcache.info().entries == 0
    monkeypatch.delenv("SO101SIM_NO_CACHE")
    modelcache.load_or_compile(scene_path(), _compile)
    assert modelcache.clear().entries == 1
    assert modelcache.info().entries == 0


@pytest.mark.slow
def test_two_processes_filling_the_cache_at_once_both_get_the_model(cache):
    code = textwrap.dedent(
        """
        from so101sim.model import load_model
        m = load_model()
        p = load_model(physics_only=True)
        print(m.nq, m.nmesh, p.ntext)
        """
    )
    env = {**os.environ, "SO101SIM_CACHE_DIR": str(cache)}
    procs = [
        subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    outs = [p.communicate(timeout=120)[0].split() for p in procs]
    assert all(p.returncode == 0 for p in procs)
    assert outs[0] == outs[1] and outs[0][2] == "1"  # the physics-only model too (its mark)
    assert len(list(cache.glob("*.mjb"))) == 2
    assert not list(cache.glob(".*.partial"))


def test_a_changed_file_is_seen_at_once_however_little_changed(cache, tmp_path):
    folder = tmp_path / "model"
    folder.mkdir()
    xml = folder / "scene.xml"
    xml.write_text("<mujoco/>")
    (folder / "mesh.stl").write_bytes(b"a" * 1000)
    first = modelcache.key_for(xml)
    stat = (folder / "mesh.stl").stat()
    (folder / "mesh.stl").write_bytes(b"b" * 1000)  # same size, same times: other content
    os.utime(folder / "mesh.stl", ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert modelcache.key_for(xml) != first
    assert not list(cache.glob("**/*.txt"))  # nothing remembered beside the entries


def _rest_pose_after_the_lab_motion(model):
    r = run_segments(Simulation(model), LAB_MOTION)
    return r.segments[-1].reached


def _foreign_model(change: str) -> mujoco.MjModel:
    spec = mujoco.MjSpec.from_file(str(scene_path()))
    if change == "gains x 0.3":
        for a in spec.actuators:
            a.gainprm[0] *= 0.3
            a.biasprm[1] *= 0.3
    elif change == "gravity 0":
        spec.option.gravity = [0, 0, 0]
    else:  # a one-joint model
        spec = mujoco.MjSpec.from_string(
            '<mujoco><worldbody><body><joint name="j" type="hinge" range="-1 1"/>'
            '<geom size="0.1"/></body></worldbody><actuator><position joint="j" kp="5"/>'
            "</actuator></mujoco>"
        )
    return spec.compile()


@pytest.mark.parametrize("with_digest", [True, False], ids=["its-digest", "stale-digest"])
@pytest.mark.parametrize("change", ["gains x 0.3", "gravity 0", "one joint"])
def test_a_foreign_entry_is_rebuilt_with_one_warning(cache, caplog, capfd, change, with_digest):
    clean = _rest_pose_after_the_lab_motion(_compile())
    modelcache.load_or_compile(scene_path(), _compile)
    entry = next(cache.glob("*.mjb"))
    foreign = _foreign_model(change)
    if with_digest:  # a valid entry of another model, with the right digest of its bytes
        modelcache._write(entry, foreign)
    else:
        mujoco.mj_saveModel(foreign, str(entry), None)
    with caplog.at_level("WARNING", logger="so101sim.model.cache"):
        rebuilt = modelcache.load_or_compile(scene_path(), _compile)
    warnings = [r for r in caplog.records if r.levelname == "WARNING"]
    assert len(warnings) == 1 and "compiling" in warnings[0].getMessage()
    assert ("another model" in warnings[0].getMessage()) == with_digest
    assert _rest_pose_after_the_lab_motion(rebuilt) == clean
    again = modelcache.load_or_compile(scene_path(), lambda: pytest.fail("compiled again"))
    assert _rest_pose_after_the_lab_motion(again) == clean  # the rebuilt entry is good
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("damage", ["truncated", "bit flipped"])
def test_a_damaged_entry_never_reaches_mujoco(cache, caplog, capfd, damage):
    modelcache.load_or_compile(scene_path(), _compile)
    physics = modelcache.load_or_compile(
        scene_path(), _compile, physics_only=True, compile_spec=compile_spec
    )
    for entry in cache.glob("*.mjb"):
        data = bytearray(entry.read_bytes())
        if damage == "truncated":
            data = data[: len(data) // 2]
        else:
            data[len(data) // 3] ^= 0x10
        entry.write_bytes(bytes(data))
    capfd.readouterr()
    with caplog.at_level("WARNING", logger="so101sim.model.cache"):
        full = modelcache.load_or_compile(scene_path(), _compile)
        again = modelcache.load_or_compile(
            scene_path(), _compile, physics_only=True, compile_spec=compile_spec
        )
    assert len([r for r in caplog.records if r.levelname == "WARNING"]) == 2  # one per entry
    assert "digest" in caplog.records[0].getMessage()
    assert capfd.readouterr().err == ""  # no "WARNING: Truncated model file" from MuJoCo
    assert full.nq == again.nq == physics.nq
    assert modelcache.info().entries == 2


def test_a_model_that_cannot_be_trimmed_is_not_tried_again(cache, tmp_path, monkeypatch):
    (tmp_path / "cloth").mkdir()  # its own folder: the key hashes the model's folder
    xml = tmp_path / "cloth" / "cloth.xml"
    xml.write_text(
        '<mujoco><worldbody><flexcomp name="f" type="grid" count="3 3 1" spacing=".1 .1 .1" '
        'dim="2"/></worldbody></mujoco>'
    )

    def compile_cloth():
        return mujoco.MjModel.from_xml_path(str(xml))

    first = modelcache.load_or_compile(
        xml, compile_cloth, physics_only=True, compile_spec=compile_spec
    )
    assert first.nflex == 1  # the full model: a flex reads the mesh trees
    assert len(list(cache.glob(f"*{modelcache.REFUSED_SUFFIX}"))) == 1
    monkeypatch.setattr(modelcache.modeltrim, "physics_only", lambda *a: pytest.fail("tried"))
    again = modelcache.load_or_compile(
        xml, compile_cloth, physics_only=True, compile_spec=compile_spec
    )
    assert again.nflex == 1
    modelcache.clear()
    assert not list(cache.glob(f"*{modelcache.REFUSED_SUFFIX}"))


def test_a_swapped_entry_is_caught_digests_included(cache, caplog):
    """Issue 30: swapping ``<key>.mjb`` with ``<key>-physics2.mjb`` (their digests too) made
    load_or_compile return the physics-only model; each entry is bound to its key and kind."""
    full = modelcache.load_or_compile(scene_path(), _compile)
    physics = modelcache.load_or_compile(
        scene_path(), _compile, physics_only=True, compile_spec=compile_spec
    )
    assert full.ngeom > physics.ngeom  # the physics-only copy has no visual geoms
    entry = next(p for p in cache.glob("*.mjb") if "-physics" not in p.name)
    other = next(p for p in cache.glob("*.mjb") if "-physics" in p.name)
    for a, b in ((entry, other), (modelcache._digest_of(entry), modelcache._digest_of(other))):
        tmp = a.with_name("swap")
        a.rename(tmp)
        b.rename(a)
        tmp.rename(b)
    with caplog.at_level("WARNING", logger="so101sim.model.cache"):
        again = modelcache.load_or_compile(scene_path(), _compile)
        again_physics = modelcache.load_or_compile(
            scene_path(), _compile, physics_only=True, compile_spec=compile_spec
        )
    assert (again.ngeom, again_physics.ngeom) == (full.ngeom, physics.ngeom)
    messages = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(messages) == 2 and all("another key or kind" in m for m in messages)


def test_cache_clear_leaves_a_folder_named_like_an_entry_with_a_warning(cache, caplog):
    modelcache.load_or_compile(scene_path(), _compile)
    (cache / "odd.mjb").mkdir()
    (cache / "odd.mjb" / "inside").write_text("x")
    with caplog.at_level("WARNING", logger="so101sim.model.cache"):
        gone = modelcache.clear()
    assert gone.entries == 1  # the folder is no entry
    assert sorted(p.name for p in cache.iterdir()) == ["odd.mjb"]
    assert "odd.mjb" in caplog.text and "by hand" in caplog.text
    assert modelcache.info().entries == 0


def test_cache_clear_on_the_command_line_with_a_folder_entry(cache, capsys):
    from so101sim import cli

    (cache).mkdir(parents=True, exist_ok=True)
    (cache / "odd.mjb").mkdir()
    assert cli.main(["cache", "clear"]) == 0
    assert "deleted 0 compiled model(s)" in capsys.readouterr().out


def test_stale_partial_files_of_a_killed_writer_are_deleted_by_the_next_write(cache):
    cache.mkdir(parents=True)
    stale, fresh = cache / ".old123.partial", cache / ".new456.partial"
    stale.write_bytes(b"half a model")
    fresh.write_bytes(b"a writer at work")
    hour_ago = os.path.getmtime(fresh) - modelcache.STALE_PARTIAL_S - 60
    os.utime(stale, (hour_ago, hour_ago))
    modelcache.load_or_compile(scene_path(), _compile)  # writes an entry
    assert not stale.exists()
    assert fresh.exists()  # a live writer's file is left alone


def test_a_model_folder_too_large_to_hash_is_said_once(cache, tmp_path, monkeypatch, caplog):
    folder = tmp_path / "big"
    folder.mkdir()
    xml = folder / "m.xml"
    xml.write_text("<mujoco><worldbody><geom size='.1'/></worldbody></mujoco>")
    monkeypatch.setattr(modelcache, "MAX_HASHED_BYTES", 10)
    with caplog.at_level("WARNING", logger="so101sim.model.cache"):
        for _ in range(3):
            modelcache.load_or_compile(xml, lambda: mujoco.MjModel.from_xml_path(str(xml)))
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warnings) == 1 and "not caching" in warnings[0] and str(folder) in warnings[0]
    assert modelcache.info().entries == 0

"""results.xdmf in ParaView: Debian's pvpython (packages paraview, python3-paraview; scripts/test.sh installs
them, scripts/setup-tests.sh) opens it with ParaView's default reader (OpenDataFile: XDMF 3) and with its
XDMF (v2) reader, without a reader error, and reads every saved field at every saved step equal to
results.h5's, on the cells of the grid, at the saved times: a 3-D run and a line-contact run, each with
pressure, displacement and gap saved."""

import json
import os
import pathlib
import shutil
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

READ = r"""
import json, sys
import numpy as np
from paraview.simple import OpenDataFile, XDMFReader, servermanager
from vtkmodules.numpy_interface import dataset_adapter as dsa
from vtkmodules.vtkFiltersCore import vtkCellCenters

path, out = sys.argv[1], sys.argv[2]
found = {}
for label, reader in (("default", OpenDataFile(path)), ("xdmf2", XDMFReader(FileNames=[path]))):
    steps = []
    for t in reader.TimestepValues:
        reader.UpdatePipeline(t)
        grid = servermanager.Fetch(reader)
        centres = vtkCellCenters()
        centres.SetInputData(grid)
        centres.Update()
        data = dsa.WrapDataObject(grid)
        arrays = {name: np.asarray(data.CellData[name]).tolist() for name in data.CellData.keys()}
        xyz = np.asarray(dsa.WrapDataObject(centres.GetOutput()).Points)
        steps.append(dict(t=t, centres=xyz[:, :2].tolist(), arrays=arrays))
    found[label] = dict(reader=reader.GetXMLName(), steps=steps)
json.dump(found, open(out, "w"))
"""

FIELDS = ["pressure", "displacement", "gap"]


def _pvpython() -> str:
    found = shutil.which("pvpython")
    assert found, ("pvpython not found: scripts/setup-tests.sh installs ParaView (apt-get install paraview "
                   "python3-paraview); tests/test_paraview.py needs it")
    return found


def _read_in_paraview(xdmf: pathlib.Path, tmp_path: pathlib.Path) -> tuple[dict, str]:
    script, out = tmp_path / "read.py", tmp_path / "read.json"
    script.write_text(READ, encoding="utf-8")
    own = ("PYTHON", "VIRTUAL_ENV", "OMPI_", "PMIX")  # this Python's and MPI's: not pvpython's
    env = {k: v for k, v in os.environ.items() if not k.startswith(own)}
    argv = [_pvpython(), "--force-offscreen-rendering", str(script), str(xdmf.resolve()), str(out)]
    done = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(out.read_text()), done.stdout + done.stderr


@pytest.mark.slow
@pytest.mark.serial
@pytest.mark.parametrize("line", [False, True], ids=["3-D", "line contact"])
def test_both_paraview_readers_read_every_field_at_every_step_as_saved(tmp_path, line):
    import petroll

    scene = petroll.load_scene(ROOT / "runs" / ("roller-2d.toml" if line else "sphere.toml"))
    scene = scene.replace({"output.fields": FIELDS, "output.every": 7})
    results = petroll.run(scene, out=tmp_path / "run")
    found, messages = _read_in_paraview(tmp_path / "run" / "results.xdmf", tmp_path)
    for word in ("ERROR", "Error", "Warning", "HDF5-DIAG", "Skipping"):
        assert word not in messages, messages[-3000:]
    times = results.series["t"][results.field_steps]
    nx, ny = len(results.x), len(results.y)
    assert len(times) >= 3 and set(results.fields) == set(FIELDS)
    saved = {name: results.field(name) for name in FIELDS}
    for label, expected_reader in (("default", "Xdmf3ReaderS"), ("xdmf2", "XdmfReader")):
        read = found[label]
        assert read["reader"] == expected_reader
        assert np.array_equal([s["t"] for s in read["steps"]], times), label
        for k, step in enumerate(read["steps"]):
            centres = np.array(step["centres"]).reshape(nx, ny, 2)  # cell k: the value k of each array
            assert np.allclose(centres[..., 0], results.x[:, None], rtol=0, atol=1e-9 * np.ptp(results.x))
            if not line:
                assert np.allclose(centres[..., 1], results.y[None, :], rtol=0, atol=1e-9 * np.ptp(results.y))
            assert sorted(step["arrays"]) == sorted(FIELDS), label
            for name in FIELDS:
                values = np.array(step["arrays"][name])
                assert values.shape == (nx * ny,), (label, name, values.shape)
                assert np.array_equal(values, saved[name][k].ravel()), (label, name, k)

#!/usr/bin/python3
"""A run's particle snapshots opened with every XDMF reader of ParaView (python3-paraview,
headless): OpenDataFile's choice (what a double-click opens: Xdmf3ReaderS), Xdmf3ReaderT and the
legacy XDMF reader. In each, the particles are points (a vertex each) with the run's count and
radius, velocity, spin and contact-count attributes, particles' positions and contacts equal the
HDF5 file's at that time, and the container's wireframe is there.

usage: paraview_test.py PDSIM SOURCE_DIR   (runs tests/decks/tiny_prescribed.toml)
"""
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np
from paraview import simple, servermanager


def blocks(data):
    it = data.NewIterator()
    it.InitTraversal()
    while not it.IsDoneWithTraversal():
        yield it.GetCurrentDataObject()
        it.GoToNextItem()


def check(label, reader, times, position, centre, contacts):
    assert np.allclose(reader.TimestepValues, times), (label, reader.TimestepValues, times)
    k = 6
    simple.UpdatePipeline(time=times[k], proxy=reader)
    found = [b for b in blocks(servermanager.Fetch(reader)) if b.GetNumberOfPoints() > 0]
    assert len(found) == 2, (label, [(b.GetClassName(), b.GetNumberOfPoints()) for b in found])
    particles, container = sorted(found, key=lambda b: -b.GetNumberOfPoints())
    assert particles.GetNumberOfPoints() == 20, (label, particles.GetNumberOfPoints())
    assert particles.GetNumberOfCells() == 20, (label, particles.GetNumberOfCells())  # drawn
    names = {particles.GetPointData().GetArrayName(i)
             for i in range(particles.GetPointData().GetNumberOfArrays())}
    assert names == {"radius", "velocity", "spin", "contacts"}, (label, names)
    counted = particles.GetPointData().GetArray("contacts")
    assert [counted.GetValue(i) for i in range(20)] == list(contacts[k]), (label, contacts[k])
    assert np.allclose(particles.GetPointData().GetArray("radius").GetValue(3), 0.002)
    for i in (0, 7, 19):
        assert np.array_equal(particles.GetPoint(i), position[k, i]), (label, i)
    # The box's 8 corners and 12 edges, centred on the container at that time.
    assert container.GetNumberOfPoints() == 8 and container.GetNumberOfCells() == 12, label
    corners = np.array([container.GetPoint(i) for i in range(8)])
    assert np.allclose(corners.mean(axis=0), centre[k], atol=1e-12), (label, corners, centre[k])
    assert np.allclose(corners.max(axis=0) - corners.min(axis=0), [0.02, 0.03, 0.02]), label


def main():
    pdsim = sys.argv[1]
    deck = os.path.join(sys.argv[2], "tests", "decks", "tiny_prescribed.toml")
    with tempfile.TemporaryDirectory() as work:
        os.chdir(work)
        subprocess.run([pdsim, "run", deck, "-o", "run.h5", "--quiet"], check=True,
                       stdout=subprocess.DEVNULL)
        with h5py.File("run.h5", "r") as h5:
            times = h5["particles/time"][()]
            position = h5["particles/damper0/position"][()]
            centre = h5["particles/damper0/container_position"][()]
            contacts = h5["particles/damper0/contacts"][()]
        assert len(times) == 10, times
        readers = {
            "OpenDataFile": lambda name: simple.OpenDataFile(name),
            "XDMFReader": lambda name: simple.XDMFReader(FileNames=[name]),
            "Xdmf3ReaderS": lambda name: simple.Xdmf3ReaderS(FileName=[name]),
            "Xdmf3ReaderT": lambda name: simple.Xdmf3ReaderT(FileName=[name]),
        }
        for label, make in readers.items():
            reader = make(os.path.join(work, "run.xdmf"))
            check(label, reader, times, position, centre, contacts)
            simple.Delete(reader)
    print("every ParaView XDMF reader reads the snapshots: 20 points, attributes, positions and "
          "the container")


if __name__ == "__main__":
    main()

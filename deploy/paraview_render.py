# SPDX-License-Identifier: MIT
"""pvbatch script (ParaView's Python): open a gearsim field record's XDMF
file with the reader ParaView picks by default for .xmf, and render von
Mises stress on the deformed gears (the recorded geometry is the current
configuration) at the given instants, one PNG each.

    pvbatch deploy/paraview_render.py RUN.xmf OUT_PREFIX T1 T2 T3

writes OUT_PREFIX_<i>.png and prints, per instant, the reader, the number of
points and cells and the von Mises range (Pa), as one JSON line each."""
import json
import sys

from paraview.simple import (ColorBy, CreateView, GetColorTransferFunction, GetScalarBar, OpenDataFile,
                             SaveScreenshot, Show, Text, UpdatePipeline)


def main():
    xmf, prefix = sys.argv[1], sys.argv[2]
    instants = [float(t) for t in sys.argv[3:]]
    reader = OpenDataFile(xmf)
    if reader is None:
        sys.exit(f"ParaView found no reader for {xmf}")
    name = reader.GetXMLName()
    times = list(getattr(reader, "TimestepValues", []) or [])
    view = CreateView("RenderView")
    view.ViewSize = [1200, 800]
    view.OrientationAxesVisibility = 0
    view.Background = [1.0, 1.0, 1.0]
    try:
        view.UseColorPaletteForBackground = 0
    except AttributeError:
        pass
    disp = Show(reader, view)
    ColorBy(disp, ("POINTS", "von_mises"))
    lut = GetColorTransferFunction("von_mises")
    if not lut.ApplyPreset("Turbo", True):
        lut.ApplyPreset("Jet", True)
    bar = GetScalarBar(lut, view)
    bar.Title = "von Mises (Pa)"
    bar.ComponentTitle = ""
    bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]
    bar.Visibility = 1
    disp.SetScalarBarVisibility(view, True)
    label = Text()
    label_disp = Show(label, view)
    label_disp.WindowLocation = "Upper Center"
    label_disp.FontSize = 14
    label_disp.Color = [0.0, 0.0, 0.0]
    for i, t in enumerate(instants):
        # the frame at or before t
        tk = max([x for x in times if x <= t + 1e-12] or times[:1])
        UpdatePipeline(time=tk, proxy=reader)
        view.ViewTime = tk
        info = reader.GetDataInformation()
        rng = reader.PointData["von_mises"].GetRange() if "von_mises" in reader.PointData.keys() else (None, None)
        lut.RescaleTransferFunction(0.0, max(rng[1] or 1.0, 1.0))
        label.Text = (f"contact_impact, t = {tk * 1e3:.1f} ms: von Mises stress on the deformed gears "
                      f"(max {rng[1] / 1e6:.0f} MPa), read by {name}")
        view.ResetCamera()
        view.CameraParallelProjection = 1
        out = f"{prefix}_{i + 1}.png"
        SaveScreenshot(out, view, ImageResolution=[1200, 800])
        print(json.dumps({"reader": name, "time": tk, "points": info.GetNumberOfPoints(),
                          "cells": info.GetNumberOfCells(), "von_mises": list(rng), "png": out}), flush=True)


main()

"""ParaView side of :mod:`dolfinx_invertible.io.paraview`: runs under ``pvbatch``, never imported.

Usage::

    pvbatch --no-mpi series.py REQUEST.json RESULT.json

``REQUEST.json`` holds ``{"command": "inspect" | "render" | "animate", ...}`` with absolute
paths; the result (or ``{"error": traceback}``) goes to ``RESULT.json``, since ParaView prints
its own messages on stdout and stderr. Only ParaView's Python (``paraview.simple`` and VTK's numpy
adapter) is used here, so the script runs with whatever Python the ParaView build embeds.
"""

import json
import sys
import traceback

import numpy
from paraview import servermanager, simple
from vtkmodules.numpy_interface import dataset_adapter
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkCellTypes, vtkImageData

#: Share of the picture's width left of the scalar bar, where the body is framed.
BODY_SHARE = 0.82


def open_series(path):
    """Return ParaView's XDMF3 reader on ``path`` (absolute) and the time steps of the file."""
    reader = simple.Xdmf3ReaderS(FileName=[path])
    reader.UpdatePipelineInformation()
    values = reader.TimestepValues
    # A file with one time step gives a bare number, a file without any an empty list.
    times = [float(values)] if isinstance(values, (int, float)) else [float(t) for t in values]
    return reader, times


def fetch(source, time):
    """Return the dataset of ``source`` at ``time`` (None: a file without time steps)."""
    if time is None:
        source.UpdatePipeline()
    else:
        source.UpdatePipeline(time)
    data = servermanager.Fetch(source)
    if not data.IsA("vtkDataSet"):
        raise ValueError(
            f"expected one grid per time step, got a {data.GetClassName()}: the file holds "
            "several grids or collections (not a ResultWriter time series)"
        )
    return data


def array_summary(vtk_array, values):
    """Components, VTK type and ranges of one array (a vector's range is its magnitude's)."""
    values = numpy.asarray(values, dtype=numpy.float64)
    components = 1 if values.ndim == 1 else values.shape[1]
    summary = {"components": components, "data_type": vtk_array.GetDataTypeAsString()}
    if values.size == 0:
        summary.update(range=None, component_ranges=None)
        return summary
    columns = values.reshape(len(values), components)
    summary["component_ranges"] = [
        [float(column.min()), float(column.max())] for column in columns.T
    ]
    if components == 1:
        summary["range"] = summary["component_ranges"][0]
    else:
        magnitude = numpy.linalg.norm(columns, axis=1)
        summary["range"] = [float(magnitude.min()), float(magnitude.max())]
    return summary


def step_summary(data, time):
    """Return counts, bounds, cell types and array summaries of one time step's dataset."""
    wrapped = dataset_adapter.WrapDataObject(data)
    point_data = data.GetPointData()
    cell_data = data.GetCellData()
    cell_types = sorted(
        {
            vtkCellTypes.GetClassNameFromTypeId(data.GetCellType(cell))
            for cell in range(data.GetNumberOfCells())
        }
    )
    summary = {
        "time": time,
        "number_of_points": int(data.GetNumberOfPoints()),
        "number_of_cells": int(data.GetNumberOfCells()),
        "bounds": [float(value) for value in data.GetBounds()],
        "cell_types": cell_types,
        "point_data": {
            point_data.GetArrayName(index): array_summary(
                point_data.GetArray(index), wrapped.PointData[point_data.GetArrayName(index)]
            )
            for index in range(point_data.GetNumberOfArrays())
        },
        "cell_data": {
            cell_data.GetArrayName(index): array_summary(
                cell_data.GetArray(index), wrapped.CellData[cell_data.GetArrayName(index)]
            )
            for index in range(cell_data.GetNumberOfArrays())
        },
        "inverted_cells": None,
    }
    if "inverted" in summary["cell_data"]:
        summary["inverted_cells"] = int(
            numpy.count_nonzero(numpy.asarray(wrapped.CellData["inverted"]) > 0.5)
        )
    return summary


def inspect(request):
    """Time steps, arrays and their ranges per step, as ParaView's XDMF3 reader sees them."""
    reader, times = open_series(request["path"])
    steps = [step_summary(fetch(reader, time), time) for time in (times or [None])]
    return {
        "path": request["path"],
        "reader": reader.GetXMLName(),
        "paraview_version": paraview_version(),
        "times": times,
        "point_arrays": sorted(reader.PointArrays),
        "cell_arrays": sorted(reader.CellArrays),
        "number_of_points": steps[0]["number_of_points"],
        "number_of_cells": steps[0]["number_of_cells"],
        "steps": steps,
    }


def inspect_vtx(request):
    """Time steps, arrays and their ranges per step of a VTX (ADIOS2) file, as ParaView reads it.

    ParaView's ADIOS2 reader starts MPI: this request runs in a ``pvbatch`` without
    ``--no-mpi``.
    """
    reader = simple.ADIOS2VTXReader(FileName=request["path"])
    reader.UpdatePipelineInformation()
    values = reader.TimestepValues
    times = [float(values)] if isinstance(values, (int, float)) else [float(t) for t in values]
    # The reader gives one block per rank's piece: one grid to summarise.
    merged = simple.MergeBlocks(Input=reader)
    steps = [step_summary(fetch(merged, time), time) for time in (times or [None])]
    return {
        "path": request["path"],
        "reader": reader.GetXMLName(),
        "paraview_version": paraview_version(),
        "times": times,
        "number_of_points": steps[0]["number_of_points"],
        "number_of_cells": steps[0]["number_of_cells"],
        "steps": steps,
    }


def paraview_version():
    """Return ParaView's full version, e.g. ``5.11.0``."""
    return simple.GetParaViewSourceVersion().split()[-1]


def telling_time(reader, times):
    """Return the first time with the most inverted cells (the last if none has any), and it."""
    if "inverted" not in reader.CellArrays:
        return times[-1], None
    # Only the one array while scanning the steps: the reader then skips the other HDF5 data.
    cell_arrays, point_arrays = list(reader.CellArrays), list(reader.PointArrays)
    reader.CellArrays, reader.PointArrays = ["inverted"], []
    best_time, best_count = times[-1], 0
    try:
        for time in times:
            values = dataset_adapter.WrapDataObject(fetch(reader, time)).CellData["inverted"]
            count = int(numpy.count_nonzero(numpy.asarray(values) > 0.5))
            if count > best_count:
                best_time, best_count = time, count
    finally:
        reader.CellArrays, reader.PointArrays = cell_arrays, point_arrays
    return best_time, best_count


def choose_time(reader, times, wanted, path):
    """Return the time step to show: ``wanted`` a number (the nearest step) or a keyword."""
    if wanted == "most-inverted":
        return telling_time(reader, times)[0]
    if wanted == "first":
        return times[0]
    if wanted == "last":
        return times[-1]
    # A little slack for a time typed from a rounded print.
    slack = 1e-9 * max(1.0, abs(times[0]), abs(times[-1]))
    if not times[0] - slack <= wanted <= times[-1] + slack:
        raise ValueError(
            f"time {wanted} lies outside the time steps of {path}, {times[0]} to {times[-1]}"
        )
    return min(times, key=lambda t: abs(t - wanted))


def frame_camera(view, points, aspect, view_direction):
    """Look at ``points`` (n, 3) from a fixed oblique direction (along -z for a flat body).

    A parallel projection whose scale fits the points as seen on the screen into the part of
    the picture left of the scalar bar, with a margin; ParaView's own ResetCamera fits the
    bounding sphere of the bounding box instead, which leaves the body small.
    """
    low, high = points.min(axis=0), points.max(axis=0)
    size = max(float(numpy.linalg.norm(high - low)), 1e-12)
    flat = high[2] - low[2] <= 1e-9 * size
    direction = numpy.array([0.0, 0.0, 1.0]) if flat else numpy.array(view_direction, float)
    direction /= numpy.linalg.norm(direction)
    up = numpy.array([0.0, 1.0, 0.0]) if flat else numpy.array([0.0, 0.0, 1.0])
    up -= (up @ direction) * direction
    up /= numpy.linalg.norm(up)
    right = numpy.cross(up, direction)
    across, along = points @ right, points @ up
    half_width = max(0.5 * float(across.max() - across.min()), 1e-9 * size)
    half_height = max(0.5 * float(along.max() - along.min()), 1e-9 * size)
    # The body gets the left BODY_SHARE of the width, the scalar bar the rest.
    scale = 1.2 * max(half_height, half_width / (BODY_SHARE * aspect))
    centre = (
        0.5 * (across.max() + across.min()) * right
        + 0.5 * (along.max() + along.min()) * up
        + float(points.mean(axis=0) @ direction) * direction
    )
    # Shifted so that the body sits left of the scalar bar and a little below the label.
    focal = centre + right * (1.0 - BODY_SHARE) * scale * aspect + up * 0.08 * scale
    view.CameraParallelProjection = 1
    view.CameraParallelScale = scale
    view.CameraFocalPoint = focal.tolist()
    view.CameraPosition = (focal + 3.0 * size * direction).tolist()
    view.CameraViewUp = up.tolist()
    # Near and far planes around the body; the camera stays where it was put.
    view.GetRenderer().ResetCameraClippingRange()


def obstacle_source(obstacles):
    """Return the grid source and the obstacles' surfaces: the zero contour of their gap.

    ``obstacles`` holds the grid (``origin``, ``spacing``, ``dimensions``) and the ``.npy`` file
    of the smallest gap to any obstacle of the group at its points, written by the package.
    """
    values = numpy.load(obstacles["values"])
    image = vtkImageData()
    image.SetDimensions(*obstacles["dimensions"])
    image.SetOrigin(*obstacles["origin"])
    image.SetSpacing(*obstacles["spacing"])
    array = numpy_support.numpy_to_vtk(values.ravel(order="F"), deep=True)
    array.SetName("gap")
    image.GetPointData().SetScalars(array)
    producer = simple.TrivialProducer()
    producer.GetClientSideObject().SetOutput(image)
    contour = simple.Contour(Input=producer, ContourBy=["POINTS", "gap"], Isosurfaces=[0.0])
    return producer, contour


def set_obstacles(producer, obstacles):
    """Replace the sampled gap of ``producer`` (a frame of a moving obstacle)."""
    image = producer.GetClientSideObject().GetOutputDataObject(0)
    values = numpy.load(obstacles["values"])
    array = numpy_support.numpy_to_vtk(values.ravel(order="F"), deep=True)
    array.SetName("gap")
    image.GetPointData().SetScalars(array)
    image.Modified()
    producer.MarkModified(producer)


class Picture:
    """The pipeline of a picture: the body, its inverted cells, the obstacles and a label."""

    def __init__(self, request, reader, cell_arrays, point_arrays, time, all_inverted):
        self.request = request
        view = self.view = simple.CreateView("RenderView")
        width, height = request["size"]
        # Font sizes in points of a 768 pixel high picture, scaled with the picture.
        font_scale = height / 768.0
        view.ViewSize = [width, height]
        view.OrientationAxesVisibility = 0
        view.UseColorPaletteForBackground = 0
        view.Background = [1.0, 1.0, 1.0]
        view.ViewTime = time

        body = reader
        displacement = request["displacement"]
        if displacement in point_arrays:
            body = simple.WarpByVector(Input=reader, Vectors=["POINTS", displacement])
            body.ScaleFactor = request["warp_scale"]
        self.body = body
        self.has_inverted = "inverted" in cell_arrays
        shown = body
        if self.has_inverted and all_inverted:
            # The body without its inverted cells: drawn over them, their faces would fight
            # with the red ones for the same pixels.
            shown = simple.Threshold(Input=body, Scalars=["CELLS", "inverted"])
            shown.LowerThreshold = 0.5
            shown.ThresholdMethod = "Below Lower Threshold"

        body_display = simple.Show(shown, view)
        body_display.Representation = "Surface With Edges"
        body_display.EdgeColor = [0.25, 0.25, 0.25]
        body_display.Opacity = request["body_opacity"]
        colour_array = request["colour_array"]
        if colour_array in cell_arrays:
            simple.ColorBy(body_display, ("CELLS", colour_array))
            lookup_table = simple.GetColorTransferFunction(colour_array)
            lookup_table.ApplyPreset(request["colour_map"], True)
            lookup_table.AutomaticRescaleRangeMode = "Never"
            lookup_table.RescaleTransferFunction(*request["colour_range"])
            bar = simple.GetScalarBar(lookup_table, view)
            bar.Title = request["colour_title"]
            bar.ComponentTitle = ""
            bar.TitleColor = [0.0, 0.0, 0.0]
            bar.LabelColor = [0.0, 0.0, 0.0]
            bar.TitleFontSize = max(6, round(18 * font_scale))
            bar.LabelFontSize = max(6, round(16 * font_scale))
            # Five round labels from end to end instead of ParaView's dense automatic ones.
            bar.UseCustomLabels = 1
            bar.CustomLabels = numpy.linspace(*request["colour_range"], 5).tolist()
            bar.AddRangeLabels = 0
            bar.AutomaticLabelFormat = 0
            bar.LabelFormat = "%.3g"
            bar.WindowLocation = "Any Location"
            bar.Position = [0.88, 0.1]
            bar.ScalarBarLength = 0.8
            body_display.SetScalarBarVisibility(view, True)
        else:
            simple.ColorBy(body_display, None)
            body_display.AmbientColor = body_display.DiffuseColor = [0.7, 0.7, 0.7]

        if self.has_inverted and all_inverted:
            inverted = simple.Threshold(Input=body, Scalars=["CELLS", "inverted"])
            inverted.LowerThreshold = 0.5
            inverted.UpperThreshold = 1.5
            inverted.ThresholdMethod = "Between"
            inverted_display = simple.Show(inverted, view)
            # Not ColorBy(None): it fails on a frame where no cell is inverted (no arrays).
            inverted_display.ColorArrayName = ["POINTS", ""]
            inverted_display.Representation = "Surface With Edges"
            inverted_display.AmbientColor = request["inverted_colour"]
            inverted_display.DiffuseColor = request["inverted_colour"]
            inverted_display.EdgeColor = [0.35, 0.0, 0.0]
            # Some ambient light keeps the faces turned away from the light recognisably red.
            inverted_display.Ambient = 0.35

        # Per group ("whole", and "cut": those between the camera and the body, drawn as a
        # cutaway without their half nearer to the camera than the middle of the body's path,
        # so that a bowl, a tube or a gap shows the body inside): its grid source and surface.
        self.obstacles = {}
        for group, grid in (request.get("obstacles") or [{}])[0].items():
            producer, surface = obstacle_source(grid)
            if group == "cut":
                surface = simple.Clip(Input=surface)
                surface.ClipType = "Plane"
                surface.ClipType.Origin = request["cutaway_origin"]
                surface.ClipType.Normal = list(request["view_direction"])
                surface.Crinkleclip = 0
            display = simple.Show(surface, view)
            display.ColorArrayName = ["POINTS", ""]
            display.AmbientColor = display.DiffuseColor = request["obstacle_colour"]
            display.Opacity = request["obstacle_opacity"]
            self.obstacles[group] = (producer, surface)

        self.label = simple.Text(Text="")
        label_display = simple.Show(self.label, view)
        label_display.WindowLocation = "Upper Left Corner"
        label_display.Color = [0.0, 0.0, 0.0]
        label_display.FontSize = max(6, round(18 * font_scale))
        label_display.Justification = "Left"

    def show(self, time, frame=0):
        """Move the pipeline to ``time``; return the warped body's dataset and inverted count."""
        self.view.ViewTime = time
        if 0 < frame < len(self.request.get("obstacles") or []):
            for group, grid in self.request["obstacles"][frame].items():
                set_obstacles(self.obstacles[group][0], grid)
        self.body.UpdatePipeline(time)
        data = fetch(self.body, time)
        inverted_cells = None
        if self.has_inverted:
            values = dataset_adapter.WrapDataObject(data).CellData["inverted"]
            inverted_cells = int(numpy.count_nonzero(numpy.asarray(values) > 0.5))
        bounds = data.GetBounds()
        sizes = [bounds[2 * axis + 1] - bounds[2 * axis] for axis in range(3)]
        # A flat (2D) body: its zero thickness says nothing.
        extent = " x ".join(f"{size:.3g}" for size in (sizes if sizes[2] > 0 else sizes[:2]))
        self.label.Text = self.request["label"].format(
            time=time, inverted=inverted_cells or 0, extent=extent
        )
        return data, inverted_cells

    def framed_points(self, data):
        """Return the points the camera fits: the body's and the obstacles' drawn near it."""
        points = [numpy.asarray(dataset_adapter.WrapDataObject(data).Points)]
        for _, surface in self.obstacles.values():
            surface.UpdatePipeline()
            drawn = servermanager.Fetch(surface)
            if drawn.GetNumberOfPoints() > 0:
                points.append(numpy.asarray(dataset_adapter.WrapDataObject(drawn).Points))
        return numpy.vstack(points)

    def save(self, png):
        """Write the view to ``png``."""
        width, height = self.request["size"]
        simple.SaveScreenshot(png, self.view, ImageResolution=[width, height],
                              TransparentBackground=0)  # fmt: skip


def render(request):
    """Warped body coloured by ``min_J``, inverted cells red on top, obstacles, bar and label."""
    reader, times = open_series(request["path"])
    # The reader's array selections: its data information is empty until it first updates.
    cell_arrays = list(reader.CellArrays)
    point_arrays = list(reader.PointArrays)
    if not times:
        raise ValueError(f"{request['path']} has no time steps")
    time = choose_time(reader, times, request["time"], request["path"])
    inverted_now = None
    if "inverted" in cell_arrays:
        values = dataset_adapter.WrapDataObject(fetch(reader, time)).CellData["inverted"]
        inverted_now = int(numpy.count_nonzero(numpy.asarray(values) > 0.5))
    picture = Picture(request, reader, cell_arrays, point_arrays, time, bool(inverted_now))
    data, inverted_cells = picture.show(time)
    # paraview.simple resets the camera on a view's first render: render once before framing.
    simple.Render(picture.view)
    width, height = request["size"]
    frame_camera(
        picture.view, picture.framed_points(data), width / height, request["view_direction"]
    )
    picture.save(request["png"])
    return {
        "png": request["png"],
        "time": time,
        "inverted_cells": inverted_cells,
        "bounds": [float(value) for value in data.GetBounds()],
        "paraview_version": paraview_version(),
    }


def animate(request):
    """One picture per time of ``request["times"]``, the camera fixed on all of them."""
    reader, times = open_series(request["path"])
    cell_arrays = list(reader.CellArrays)
    point_arrays = list(reader.PointArrays)
    frames = [choose_time(reader, times, wanted, request["path"]) for wanted in request["times"]]
    picture = Picture(request, reader, cell_arrays, point_arrays, frames[0], True)
    points = []
    for index, time in enumerate(frames):
        data, _ = picture.show(time, index)
        points.append(picture.framed_points(data))
    simple.Render(picture.view)
    width, height = request["size"]
    frame_camera(picture.view, numpy.vstack(points), width / height, request["view_direction"])
    pngs = []
    for index, time in enumerate(frames):
        picture.show(time, index)
        png = request["png_pattern"].format(index=index)
        picture.save(png)
        pngs.append(png)
    return {"pngs": pngs, "times": frames, "paraview_version": paraview_version()}


COMMANDS = {"inspect": inspect, "inspect_vtx": inspect_vtx, "render": render, "animate": animate}


def main(argv):
    """Run the request in ``argv[1]``, write the result to ``argv[2]``; 1 if it raised."""
    request_path, result_path = argv[1], argv[2]
    with open(request_path, encoding="utf-8") as stream:
        request = json.load(stream)
    try:
        result = COMMANDS[request["command"]](request)
    except Exception:  # reported to the calling process, which raises it there
        result = {"error": traceback.format_exc()}
    with open(result_path, "w", encoding="utf-8") as stream:
        json.dump(result, stream)
    return 1 if "error" in result else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

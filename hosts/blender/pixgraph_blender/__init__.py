"""pixgraph for Blender: a soft shadow for a cutout composited onto a background
photo, computed by pixgraph in Blender's own Python (Image editor > sidebar > pixgraph).

pixgraph itself must be importable from Blender's Python (see docs/blender.md):
``<blender python> -m pip install pixgraph`` or ``PIXGRAPH_PATH`` / ``PYTHONPATH``.
"""
from __future__ import annotations

bl_info = {  # legacy add-on install (Blender < 4.2 style); 4.2+ reads blender_manifest.toml
    "name": "pixgraph",
    "author": "pixgraph",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "Image Editor > Sidebar > pixgraph",
    "description": "Pixel-height soft shadows for cutouts on photos (PixHt-Lab)",
    "category": "Compositing",
}

import os
import sys
import threading

import bpy
from bpy.props import (EnumProperty, FloatProperty, FloatVectorProperty, IntProperty, PointerProperty,
                       StringProperty)

from . import mapping

_session = None          # one pixgraph Session per Blender process: its cache serves reruns
_running = threading.Event()   # set while a run is in flight: one at a time per session


def _pixgraph():
    """Import pixgraph, from PIXGRAPH_PATH when set; the error says how to install it."""
    extra = os.environ.get("PIXGRAPH_PATH")
    if extra and extra not in sys.path:
        sys.path.append(extra)
    try:
        import pixgraph.session  # noqa: F401
        import pixgraph_nodes  # noqa: F401
    except ImportError as e:
        raise mapping.HostError(f"pixgraph is not installed in Blender's Python ({e}); "
                                f"run: {sys.executable} -m pip install pixgraph") from None
    return pixgraph


def session():
    global _session
    if _session is None:
        _pixgraph()
        from pixgraph.session import Session
        _session = Session(cache_bytes=512 * 2**20)
    return _session


# -- Blender images <-> arrays ---------------------------------------------------

def image_array(image):
    """(array float32 (H, W, 4) rows from the top, colorspace, alpha) of a Blender image.

    Float images hold scene-linear premultiplied pixels; byte images hold their
    file's values (sRGB unless their colour space is Non-Color/linear) with straight alpha.
    """
    import numpy as np

    w, h = image.size
    if w == 0 or h == 0:
        raise mapping.HostError(f"image {image.name!r} has no pixels (is its file missing?)")
    buf = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(buf)
    arr = buf.reshape(h, w, 4)[::-1].copy()           # Blender's rows start at the bottom
    space = image.colorspace_settings.name.lower()
    if image.is_float:
        return arr, "linear", "premultiplied"
    colorspace = "srgb" if "srgb" in space else "linear"
    return arr, colorspace, "straight"


def write_image(name, array, *, data: bool):
    """Put a float array (H, W[, C]) rows from the top into Blender image ``name``
    (created or resized): scene-linear colour, or non-colour data (``data``)."""
    import numpy as np

    a = np.asarray(array, np.float32)
    if a.ndim == 2:
        a = a[..., None]
    h, w, c = a.shape
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = a[..., :3] if c >= 3 else a[..., :1]
    if c == 4:
        rgba[..., 3] = a[..., 3]
    img = bpy.data.images.get(name)
    if img is None or tuple(img.size) != (w, h) or not img.is_float:
        if img is not None:
            bpy.data.images.remove(img)
        img = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True)
    img.colorspace_settings.name = "Non-Color" if data else _linear_name()
    img.pixels.foreach_set(rgba[::-1].ravel())
    img.update()
    img.pack()          # keep the result in the .blend: it has no file of its own
    return img


def _linear_name():
    names = {i.name for i in bpy.types.ColorManagedInputColorspaceSettings.bl_rna.properties["name"].enum_items}
    for n in ("Linear Rec.709", "Linear"):
        if n in names:
            return n
    return "scene_linear"


# -- the run ---------------------------------------------------------------------

class Job:
    """One pixgraph run: arrays gathered in the main thread, run in any thread."""

    def __init__(self, context):
        _pixgraph()
        s = context.scene.pixgraph
        if s.background is None or s.cutout is None:
            raise mapping.HostError("choose a background image and a cutout image")
        self.props = s
        bg, bg_space, bg_alpha = image_array(s.background)
        cut, cut_space, cut_alpha = image_array(s.cutout)
        if bg.shape != cut.shape:
            raise mapping.HostError(f"the cutout is {cut.shape[1]}x{cut.shape[0]} but the background is "
                                    f"{bg.shape[1]}x{bg.shape[0]}; they must have the same size")
        h, w = bg.shape[:2]
        camera = self._camera(context, w, h)
        alpha = cut[..., 3]
        light = self._light(context, camera, mapping.foot_uv(alpha))
        template = {"kind": s.template}
        if s.template == "back_wall":
            template.update(junction_row=s.junction_row, junction_slope=s.junction_slope)
        elif s.template == "wall_corner":
            template.update(corner=list(s.corner), left_slope=s.left_slope, right_slope=s.right_slope)
        sess = session()
        self.graph = mapping.build_graph(sess.builder(), camera=camera, light=light, template=template,
                                         samples=s.samples, opacity=s.opacity, tint=list(s.tint),
                                         thickness=s.thickness, height_method=s.height_method,
                                         background_colorspace=bg_space, background_alpha=bg_alpha,
                                         cutout_colorspace=cut_space, cutout_alpha=cut_alpha)
        self.bind = {"background": bg[..., :3], "cutout": cut}
        self.names = (s.composite_name, s.shadow_name)
        from pixgraph.events import CancelToken
        self.cancel = CancelToken()
        self.fraction = 0.0
        self.status = "starting"
        self.result = None
        self.error = None

    @staticmethod
    def _camera(context, w, h):
        s = context.scene.pixgraph
        cam = s.camera or context.scene.camera
        if cam is None or cam.type != "CAMERA":
            raise mapping.HostError("the scene has no camera (set one, or pick one in the panel)")
        d = cam.data
        return mapping.camera_params(lens_mm=d.lens, sensor_width_mm=d.sensor_width,
                                     sensor_height_mm=d.sensor_height, sensor_fit=d.sensor_fit,
                                     shift_x=d.shift_x, shift_y=d.shift_y, width=w, height=h,
                                     matrix_world=[list(r) for r in cam.matrix_world], cam_type=d.type,
                                     pixel_aspect=context.scene.render.pixel_aspect_y
                                     / context.scene.render.pixel_aspect_x)

    @staticmethod
    def _light(context, camera, foot):
        s = context.scene.pixgraph
        cam = s.camera or context.scene.camera
        M = [list(r) for r in cam.matrix_world]
        obj = s.light
        if obj is None:        # panel values
            return {"kind": "disk", "placement": "controls", "target_mode": "pixel", "target_uv": list(foot),
                    "azimuth": s.azimuth, "elevation": s.elevation, "distance": s.distance, "radius": s.radius}
        if obj.type != "LIGHT":
            raise mapping.HostError(f"{obj.name!r} is not a light")
        L = obj.data
        if L.type == "SUN":
            import mathutils
            direction = obj.matrix_world.to_3x3() @ mathutils.Vector((0.0, 0.0, 1.0))  # suns shine along -Z
            import math
            return mapping.light_params(camera, M, foot, kind="directional", direction=list(direction),
                                        angular_radius_deg=math.degrees(L.angle) / 2.0)
        if L.type == "AREA":
            radius = 0.5 * max(L.size, L.size_y if L.shape in ("RECTANGLE", "ELLIPSE") else L.size)
        else:                  # POINT, SPOT: the soft-shadow radius
            radius = L.shadow_soft_size
        return mapping.light_params(camera, M, foot, kind="disk" if radius > 0 else "point",
                                    location=list(obj.matrix_world.translation), radius=radius)

    def on_event(self, event):
        from pixgraph import events as E
        if isinstance(event, E.RunStarted):
            self._total, self._done = max(1, event.to_run), 0
        elif isinstance(event, E.NodeStarted):
            self.status = f"{event.node_id} ({event.reason})"
        elif isinstance(event, E.NodeProgress):
            self.fraction = (self._done + event.fraction) / self._total
            self.status = f"{event.node_id} {event.fraction:.0%} {event.message}"
        elif isinstance(event, E.NodeFinished):
            self._done += 1
            self.fraction = self._done / self._total

    def run(self):
        _running.set()
        try:
            self.result = session().run(self.graph, bind=self.bind, cancel=self.cancel, on_event=self.on_event)
        except BaseException as e:      # reported in the main thread
            self.error = e
        finally:
            _running.clear()

    def finish(self):
        """Write the results as Blender images (main thread only). Returns the images."""
        comp = write_image(self.names[0], self.result["composite"], data=False)
        shadow = write_image(self.names[1], self.result["shadow"], data=True)
        return comp, shadow


def _message(e):
    from pixgraph.events import Cancelled
    if isinstance(e, Cancelled):
        return "cancelled"
    return str(e).splitlines()[0] if str(e) else type(e).__name__


class PIXGRAPH_OT_composite(bpy.types.Operator):
    """Composite the cutout onto the background with a pixel-height soft shadow"""
    bl_idname = "pixgraph.composite"
    bl_label = "Composite with shadow"
    bl_options = {"REGISTER"}

    _timer = None
    _job = None
    _thread = None

    @classmethod
    def poll(cls, context):
        if _running.is_set():
            cls.poll_message_set("pixgraph is already running (Esc cancels it)")
            return False
        return True

    def _start(self, context):
        try:
            self._job = Job(context)
        except (mapping.HostError, ValueError) as e:
            self.report({"ERROR"}, _message(e))
            return False
        return True

    def _done(self, context):
        job = self._job
        if job.error is not None:
            self.report({"WARNING"} if _message(job.error) == "cancelled" else {"ERROR"},
                        f"pixgraph: {_message(job.error)}")
            return {"CANCELLED"}
        comp, shadow = job.finish()
        self.report({"INFO"}, f"pixgraph: wrote images {comp.name!r} and {shadow.name!r}")
        return {"FINISHED"}

    def execute(self, context):           # blocking: scripts, headless Blender, F3 search
        if not self._start(context):
            return {"CANCELLED"}
        self._job.run()
        return self._done(context)

    def invoke(self, context, event):     # interactive: runs in a thread, progress bar, Esc cancels
        if not self._start(context):
            return {"CANCELLED"}
        self._thread = threading.Thread(target=self._job.run, name="pixgraph", daemon=True)
        self._thread.start()
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        context.workspace.status_text_set("pixgraph: running (Esc to cancel)")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC":
            job.cancel.cancel()         # the run stops where it next checks; the timer sees it end
            return {"RUNNING_MODAL"}
        if event.type == "TIMER":
            context.window_manager.progress_update(int(100 * job.fraction))
            context.workspace.status_text_set(f"pixgraph: {job.fraction:.0%} {job.status} (Esc to cancel)")
            if not self._thread.is_alive():
                self._end(context)
                return self._done(context)
            return {"RUNNING_MODAL"}
        return {"PASS_THROUGH"}        # Blender stays usable while pixgraph runs

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)


class PixgraphSettings(bpy.types.PropertyGroup):
    background: PointerProperty(type=bpy.types.Image, name="Background", description="the photo (any size)")
    cutout: PointerProperty(type=bpy.types.Image, name="Cutout",
                            description="the cutout with alpha, the background's size, standing on the ground")
    camera: PointerProperty(type=bpy.types.Object, name="Camera", poll=lambda self, o: o.type == "CAMERA",
                            description="level camera the photo was taken with (default: the scene camera)")
    light: PointerProperty(type=bpy.types.Object, name="Light", poll=lambda self, o: o.type == "LIGHT",
                           description="a light object (point, spot, area, sun); empty: the values below")
    azimuth: FloatProperty(name="Azimuth", default=20.0, min=-360.0, max=360.0,
                           description="degrees around the vertical; 0 = camera side, 90 = right")
    elevation: FloatProperty(name="Elevation", default=45.0, min=1.0, max=90.0, description="degrees")
    distance: FloatProperty(name="Distance", default=4.0, min=0.001, unit="LENGTH",
                            description="from the cutout's foot")
    radius: FloatProperty(name="Radius", default=0.3, min=0.0, unit="LENGTH", description="disk light radius")
    template: EnumProperty(name="Background", items=[
        ("ground", "Ground", "a flat ground to the horizon"),
        ("back_wall", "Back wall", "floor and a wall meeting on a junction line"),
        ("wall_corner", "Wall corner", "floor and two walls meeting in a corner"),
    ], default="ground")
    junction_row: FloatProperty(name="Junction row", default=300.0, description="pixels from the top, at the centre")
    junction_slope: FloatProperty(name="Junction slope", default=0.0, description="rows per column")
    corner: FloatVectorProperty(name="Corner", size=2, default=(256.0, 300.0),
                                description="the corner's (column, row) in pixels from the top left")
    left_slope: FloatProperty(name="Left slope", default=-0.3)
    right_slope: FloatProperty(name="Right slope", default=0.3)
    height_method: EnumProperty(name="Cutout height", items=[
        ("contact_line", "Contact line", "from the alpha: right for an upright object facing the camera"),
        ("learned", "Learned", "a small network reads the cutout's colour and alpha (docs/height.md)"),
        ("auto", "Auto", "learned, unless its confidence rule says the contact line is likely better"),
    ], default="contact_line")
    samples: IntProperty(name="Samples", default=48, min=1, max=65536, description="light samples")
    thickness: FloatProperty(name="Thickness", default=6.0, min=0.0, max=1000.0,
                             description="occluder thickness in pixels (how deep the cutout is, for its shadow)")
    opacity: FloatProperty(name="Opacity", default=0.85, min=0.0, max=1.0, description="shadow strength")
    tint: FloatVectorProperty(name="Tint", size=3, subtype="COLOR", default=(0.08, 0.09, 0.12), min=0.0, max=1.0,
                              description="fraction of each channel that survives full shadow (sky fill)")
    composite_name: StringProperty(name="Composite image", default="pixgraph composite")
    shadow_name: StringProperty(name="Shadow image", default="pixgraph shadow")


class PIXGRAPH_PT_panel(bpy.types.Panel):
    bl_label = "pixgraph shadow"
    bl_space_type = "IMAGE_EDITOR"
    bl_region_type = "UI"
    bl_category = "pixgraph"

    def draw(self, context):
        s = context.scene.pixgraph
        col = self.layout.column()
        col.template_ID(s, "background", open="image.open")
        col.template_ID(s, "cutout", open="image.open")
        col.prop(s, "camera")
        col.prop(s, "light")
        if s.light is None:
            for p in ("azimuth", "elevation", "distance", "radius"):
                col.prop(s, p)
        col.prop(s, "template")
        for p in mapping.TEMPLATE_PARAMS[s.template]:
            col.prop(s, p)
        col.prop(s, "height_method")
        col.prop(s, "samples")
        col.prop(s, "thickness")
        col.prop(s, "opacity")
        col.prop(s, "tint")
        col.prop(s, "composite_name")
        col.prop(s, "shadow_name")
        col.operator(PIXGRAPH_OT_composite.bl_idname, icon="RENDER_STILL")


_classes = (PixgraphSettings, PIXGRAPH_OT_composite, PIXGRAPH_PT_panel)


def register():
    for c in _classes:
        bpy.utils.register_class(c)
    bpy.types.Scene.pixgraph = PointerProperty(type=PixgraphSettings)


def unregister():
    del bpy.types.Scene.pixgraph
    for c in reversed(_classes):
        bpy.utils.unregister_class(c)

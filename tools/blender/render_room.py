"""Render a procedural room with Blender as a TUM RGB-D folder that rdslam replays.

A second, independent renderer for evaluating rdslam (issue 22, item 2): the scene, its
materials, lights and camera path are built here in Python from Blender's own node
system (noise, Voronoi, brick, wave, Musgrave, checker and magic textures mixed into
random materials), so nothing is shared with rdslam's rasteriser (drivers/synth_*) except
the output format. No assets are downloaded or read.

Run with Blender 3.4 (Debian's `blender` package) in background mode:

    blender -b -noaudio --factory-startup -t 1 -P tools/blender/render_room.py -- \
        --scene static --out DIR [--frames N] [--seed S] [--width 640 --height 480] \
        [--engine cycles|eevee] [--samples K] [--motion-blur] [--fx F]

(tools/blender/render.sh wraps this with `nice` and, for Eevee, `xvfb-run`.)

Variants (--scene):
  static      hand-held orbit (about 60 degrees of azimuth in 5 s) around the furniture,
              with vertical/radial sway and high-frequency jitter
  walking     the same camera; two people-sized textured figures cross the view
  rearranged  the same camera; boxes are moved during the sequence and one is removed
  dominant    hand-held translation in front of one large, strongly textured panel that
              covers 40-70% of the image (the room is low in contrast); the panel stands
              still for 1 s, then slides sideways and back

Output folder (read by `rdslam replay tum:DIR`):
  rgb/NNNNNN.png, rgb.txt   8-bit RGB frames, `stamp rgb/NNNNNN.png`, stamp = i / fps
  groundtruth.txt           TUM `stamp tx ty tz qx qy qz qw`: T_world_cam, camera in the
                            OpenCV convention (x right, y down, z forward); world z up
  camera.yaml               pinhole intrinsics from the Blender sensor, lens and resolution
  mask/NNNNNN.png           (Cycles only) 255 where an object that moves or has moved since
                            frame 0 is seen (object index pass), else 0
  markers.txt               world positions of the small magenta marker spheres
  objects.txt               per frame, pose and visibility of every object that moves
  scene.json                arguments, object events, render settings and timings

Conventions: Blender's camera looks down its local -Z with +Y up; the OpenCV camera is the
same frame rotated by 180 degrees about x, so T_world_cam = T_world_blendercam * diag(1,-1,-1).
The sensor is fitted horizontally (sensor width 36 mm, lens = fx * 36 / width mm, no
shift), so fx = fy = lens * width / 36 and the principal point is the image centre: with
pixel (0, 0) centred at (0, 0), cx = (width - 1) / 2, cy = (height - 1) / 2.
tools/blender/check_projection.py verifies all of this on rendered frames.
"""

import argparse
import json
import math
import os
import random
import sys
import time

import bmesh
import bpy
from mathutils import Matrix, Quaternion, Vector

VARIANTS = ("static", "walking", "rearranged", "dominant")
ROOM = (6.0, 5.0, 2.7)  # x, y, z extents in metres; floor at z = 0, centred on x and y
MOVING_INDEX = 1  # object pass index of things that move or have moved


# ----------------------------------------------------------------------------- arguments

def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="render_room.py", description=__doc__.split("\n")[0])
    p.add_argument("--scene", choices=VARIANTS, default="static")
    p.add_argument("--out", required=True, help="output folder (created; must be empty)")
    p.add_argument("--frames", type=int, default=150)
    p.add_argument("--first", type=int, default=0, help="first frame to render (resume)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=480)
    p.add_argument("--fx", type=float, default=525.0, help="focal length in pixels (fy = fx)")
    p.add_argument("--engine", choices=("cycles", "eevee"), default="eevee")
    p.add_argument("--samples", type=int,
                   help="Cycles path samples (default 16) or Eevee TAA samples (default 4)")
    p.add_argument("--denoise", action="store_true", help="Cycles: OpenImageDenoise if built in")
    p.add_argument("--motion-blur", action="store_true", help="shutter 0.5 frame")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--no-markers", action="store_true", help="leave out the marker spheres")
    p.add_argument("--save-blend", help="also save the built scene as this .blend file")
    a = p.parse_args(argv)
    if a.samples is None:
        a.samples = 16 if a.engine == "cycles" else 4
    if a.frames < 1 or a.width < 16 or a.height < 16 or a.samples < 1:
        p.error("frames, width, height and samples must be positive")
    return a


# ----------------------------------------------------------------------------- materials

def hsv(h, s, v):
    """Linear RGBA from hue/saturation/value (saturation kept below 0.75 so that no
    material is as saturated as the magenta markers)."""
    s = min(s, 0.75)
    i = int(h * 6.0) % 6
    f = h * 6.0 - math.floor(h * 6.0)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    r, g, b = [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)][i]
    return (r ** 2.2, g ** 2.2, b ** 2.2, 1.0)


class MaterialFactory:
    """Random procedural materials: two patterns mixed by a large-scale noise, so that
    regular patterns (bricks, checkers) do not repeat identically across a surface."""

    def __init__(self, rng, contrast=1.0):
        self.rng = rng
        self.contrast = contrast
        self.count = 0

    def palette(self, n):
        r = self.rng
        h0 = r.random()
        cols = []
        for k in range(n):
            h = (h0 + r.choice((0.0, 0.08, 0.33, 0.5, 0.6)) * k + r.uniform(-0.04, 0.04)) % 1.0
            v = r.choice((0.12, 0.3, 0.55, 0.8, 0.95)) if k else r.uniform(0.5, 0.95)
            cols.append(hsv(h, r.uniform(0.1, 0.7), v))
        return cols

    def _ramp(self, nt, fac_socket, cols, hard=False):
        ramp = nt.nodes.new("ShaderNodeValToRGB")
        if hard:
            ramp.color_ramp.interpolation = "CONSTANT"
        els = ramp.color_ramp.elements
        els[0].position, els[0].color = 0.0, cols[0]
        els[1].position, els[1].color = 1.0, cols[-1]
        for k, c in enumerate(cols[1:-1], start=1):
            e = els.new(k / (len(cols) - 1) + self.rng.uniform(-0.08, 0.08))
            e.color = c
        nt.links.new(fac_socket, ramp.inputs["Fac"])
        return ramp.outputs["Color"]

    def _pattern(self, nt, vec, scale):
        """One textured colour socket; `scale` is the feature size in 1/m."""
        r = self.rng
        kind = r.choice(("cells", "bricks", "marble", "spots", "checker", "magic", "stone",
                         "stripes"))
        n = nt.nodes
        if kind == "cells":
            t = n.new("ShaderNodeTexVoronoi")
            t.inputs["Scale"].default_value = scale * r.uniform(0.8, 1.6)
            t.inputs["Randomness"].default_value = r.uniform(0.6, 1.0)
            nt.links.new(vec, t.inputs["Vector"])
            noise = n.new("ShaderNodeTexVoronoi")
            noise.feature = "F1"
            noise.inputs["Scale"].default_value = scale * 3.1
            nt.links.new(vec, noise.inputs["Vector"])
            mix = n.new("ShaderNodeMixRGB")
            mix.blend_type = "MULTIPLY"
            mix.inputs["Fac"].default_value = 0.7
            cols = self._ramp(nt, t.outputs["Distance"], self.palette(3), hard=True)
            nt.links.new(cols, mix.inputs["Color1"])
            nt.links.new(noise.outputs["Color"], mix.inputs["Color2"])
            return mix.outputs["Color"], t.outputs["Distance"]
        if kind == "bricks":
            t = n.new("ShaderNodeTexBrick")
            c = self.palette(3)
            t.inputs["Color1"].default_value = c[0]
            t.inputs["Color2"].default_value = c[1]
            t.inputs["Mortar"].default_value = c[2]
            t.inputs["Scale"].default_value = scale * r.uniform(0.3, 0.6)
            t.inputs["Mortar Size"].default_value = r.uniform(0.01, 0.04)
            t.inputs["Bias"].default_value = r.uniform(-0.6, 0.6)
            t.inputs["Brick Width"].default_value = r.uniform(0.4, 0.9)
            t.inputs["Row Height"].default_value = r.uniform(0.2, 0.35)
            nt.links.new(vec, t.inputs["Vector"])
            return t.outputs["Color"], t.outputs["Fac"]
        if kind == "marble":
            w = n.new("ShaderNodeTexWave")
            w.wave_type = r.choice(("BANDS", "RINGS"))
            w.inputs["Scale"].default_value = scale * r.uniform(0.3, 0.8)
            w.inputs["Distortion"].default_value = r.uniform(4, 12)
            w.inputs["Detail"].default_value = 6
            w.inputs["Detail Scale"].default_value = r.uniform(1, 3)
            nt.links.new(vec, w.inputs["Vector"])
            return self._ramp(nt, w.outputs["Fac"], self.palette(4)), w.outputs["Fac"]
        if kind == "spots":
            base = n.new("ShaderNodeTexNoise")
            base.inputs["Scale"].default_value = scale * 2.0
            base.inputs["Detail"].default_value = 8
            nt.links.new(vec, base.inputs["Vector"])
            v = n.new("ShaderNodeTexVoronoi")
            v.inputs["Scale"].default_value = scale * r.uniform(1.5, 3.0)
            nt.links.new(vec, v.inputs["Vector"])
            cols = self.palette(4)
            a = self._ramp(nt, base.outputs["Fac"], cols[:2])
            spot = n.new("ShaderNodeMath")
            spot.operation = "LESS_THAN"
            spot.inputs[1].default_value = r.uniform(0.15, 0.3)
            nt.links.new(v.outputs["Distance"], spot.inputs[0])
            mix = n.new("ShaderNodeMixRGB")
            nt.links.new(spot.outputs[0], mix.inputs["Fac"])
            nt.links.new(a, mix.inputs["Color1"])
            nt.links.new(v.outputs["Color"], mix.inputs["Color2"])
            return mix.outputs["Color"], base.outputs["Fac"]
        if kind == "checker":
            dist = n.new("ShaderNodeTexNoise")
            dist.inputs["Scale"].default_value = scale * 0.7
            nt.links.new(vec, dist.inputs["Vector"])
            add = n.new("ShaderNodeVectorMath")
            add.operation = "MULTIPLY_ADD"
            add.inputs[1].default_value = (0.15 / scale,) * 3
            nt.links.new(dist.outputs["Color"], add.inputs[0])
            nt.links.new(vec, add.inputs[2])
            t = n.new("ShaderNodeTexChecker")
            c = self.palette(2)
            t.inputs["Color1"].default_value = c[0]
            t.inputs["Color2"].default_value = c[1]
            t.inputs["Scale"].default_value = scale * r.uniform(0.3, 0.7)
            nt.links.new(add.outputs[0], t.inputs["Vector"])
            return t.outputs["Color"], t.outputs["Fac"]
        if kind == "magic":
            t = n.new("ShaderNodeTexMagic")
            t.turbulence_depth = r.randint(2, 4)
            t.inputs["Scale"].default_value = scale * r.uniform(0.2, 0.5)
            t.inputs["Distortion"].default_value = r.uniform(1, 3)
            nt.links.new(vec, t.inputs["Vector"])
            return self._ramp(nt, t.outputs["Fac"], self.palette(4)), t.outputs["Fac"]
        if kind == "stone":
            t = n.new("ShaderNodeTexMusgrave")
            t.musgrave_type = r.choice(("FBM", "RIDGED_MULTIFRACTAL", "HETERO_TERRAIN"))
            t.inputs["Scale"].default_value = scale * r.uniform(0.5, 1.2)
            t.inputs["Detail"].default_value = 8
            t.inputs["Dimension"].default_value = r.uniform(0.3, 1.0)
            nt.links.new(vec, t.inputs["Vector"])
            norm = n.new("ShaderNodeMapRange")
            norm.clamp = True
            norm.inputs["From Min"].default_value = -0.6
            norm.inputs["From Max"].default_value = 0.9
            nt.links.new(t.outputs["Fac"], norm.inputs["Value"])
            return self._ramp(nt, norm.outputs["Result"], self.palette(4)), t.outputs["Fac"]
        # stripes: hard-edged bands of several colours, warped by noise
        w = n.new("ShaderNodeTexWave")
        w.bands_direction = r.choice(("X", "Y", "Z", "DIAGONAL"))
        w.inputs["Scale"].default_value = scale * r.uniform(0.2, 0.5)
        w.inputs["Distortion"].default_value = r.uniform(0.5, 3)
        w.inputs["Detail"].default_value = 3
        nt.links.new(vec, w.inputs["Vector"])
        return self._ramp(nt, w.outputs["Fac"], self.palette(5), hard=True), w.outputs["Fac"]

    def make(self, name, scale=8.0, contrast=None, roughness=None, bump=True):
        """A Principled material on object coordinates (metres). `scale`: features per
        metre; `contrast` (default: the factory's) blends towards flat grey."""
        r = self.rng
        self.count += 1
        mat = bpy.data.materials.new(f"{name}_{self.count}")
        mat.use_nodes = True
        nt = mat.node_tree
        bsdf = nt.nodes["Principled BSDF"]
        coord = nt.nodes.new("ShaderNodeTexCoord")
        mapping = nt.nodes.new("ShaderNodeMapping")
        mapping.inputs["Location"].default_value = (r.uniform(-50, 50), r.uniform(-50, 50),
                                                    r.uniform(-50, 50))
        mapping.inputs["Rotation"].default_value = (r.uniform(0, 6.3), r.uniform(0, 6.3),
                                                    r.uniform(0, 6.3))
        nt.links.new(coord.outputs["Object"], mapping.inputs["Vector"])
        vec = mapping.outputs["Vector"]
        col_a, fac_a = self._pattern(nt, vec, scale)
        col_b, _ = self._pattern(nt, vec, scale * r.uniform(0.5, 2.0))
        big = nt.nodes.new("ShaderNodeTexNoise")
        big.inputs["Scale"].default_value = r.uniform(0.6, 1.5)
        big.inputs["Detail"].default_value = 2
        nt.links.new(vec, big.inputs["Vector"])
        sharpen = nt.nodes.new("ShaderNodeMapRange")
        sharpen.clamp = True
        sharpen.inputs["From Min"].default_value = 0.42
        sharpen.inputs["From Max"].default_value = 0.58
        nt.links.new(big.outputs["Fac"], sharpen.inputs["Value"])
        mix = nt.nodes.new("ShaderNodeMixRGB")
        nt.links.new(sharpen.outputs["Result"], mix.inputs["Fac"])
        nt.links.new(col_a, mix.inputs["Color1"])
        nt.links.new(col_b, mix.inputs["Color2"])
        out = mix.outputs["Color"]
        c = self.contrast if contrast is None else contrast
        if c < 1.0:
            flat = nt.nodes.new("ShaderNodeMixRGB")
            flat.inputs["Fac"].default_value = 1.0 - c
            flat.inputs["Color2"].default_value = (0.25, 0.24, 0.22, 1.0)
            nt.links.new(out, flat.inputs["Color1"])
            out = flat.outputs["Color"]
        nt.links.new(out, bsdf.inputs["Base Color"])
        bsdf.inputs["Roughness"].default_value = (r.uniform(0.35, 0.9) if roughness is None
                                                  else roughness)
        bsdf.inputs["Specular"].default_value = r.uniform(0.2, 0.5)
        if bump:
            b = nt.nodes.new("ShaderNodeBump")
            b.inputs["Strength"].default_value = r.uniform(0.05, 0.25) * c
            b.inputs["Distance"].default_value = 0.01
            nt.links.new(fac_a, b.inputs["Height"])
            nt.links.new(b.outputs["Normal"], bsdf.inputs["Normal"])
        return mat

    def plain(self, name, color, roughness=0.6):
        mat = bpy.data.materials.new(name)
        mat.use_nodes = True
        bsdf = mat.node_tree.nodes["Principled BSDF"]
        bsdf.inputs["Base Color"].default_value = color
        bsdf.inputs["Roughness"].default_value = roughness
        return mat


def emission_material(name, color, strength):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = color
    em.inputs["Strength"].default_value = strength
    nt.links.new(em.outputs["Emission"], nt.nodes["Material Output"].inputs["Surface"])
    return mat


# ----------------------------------------------------------------------------- geometry

def mesh_object(name, build, material, location=(0, 0, 0), rot_z=0.0, parent=None,
                smooth=False):
    """An object whose mesh `build(bm)` creates in metres around its origin."""
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    build(bm)
    bm.to_mesh(me)
    bm.free()
    if smooth:
        for poly in me.polygons:
            poly.use_smooth = True
    ob = bpy.data.objects.new(name, me)
    ob.data.materials.append(material)
    ob.location = location
    ob.rotation_euler = (0.0, 0.0, rot_z)
    if parent is not None:
        ob.parent = parent
    bpy.context.scene.collection.objects.link(ob)
    return ob


def box(name, size, material, location=(0, 0, 0), rot_z=0.0, parent=None):
    """An axis-aligned box of `size` (x, y, z) centred on its origin."""
    def build(bm):
        bmesh.ops.create_cube(bm, size=1.0)
        bmesh.ops.scale(bm, vec=Vector(size), verts=bm.verts)
    return mesh_object(name, build, material, location, rot_z, parent)


def sphere(name, radius, material, location=(0, 0, 0), parent=None, segments=32):
    def build(bm):
        bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=segments // 2,
                                  radius=radius)
    return mesh_object(name, build, material, location, 0.0, parent, smooth=True)


def empty(name, location=(0, 0, 0)):
    ob = bpy.data.objects.new(name, None)
    ob.location = location
    bpy.context.scene.collection.objects.link(ob)
    return ob


# ----------------------------------------------------------------------------- the room

class Room:
    """Walls, floor, ceiling, furniture, lights and markers. Positions are jittered by the
    seed; the layout keeps the space between the camera (south, y < -1) and the furniture
    (north half) free for walking figures and the dominant panel."""

    def __init__(self, rng, mats, args):
        self.rng, self.mats, self.args = rng, mats, args
        self.markers = []
        self.movable = {}

    def build(self):
        r, m = self.rng, self.mats
        w, d, h = ROOM
        t = 0.1
        box("floor", (w, d, t), m.make("floor", scale=r.uniform(3, 6)), (0, 0, -t / 2))
        box("ceiling", (w, d, t), m.make("ceiling", scale=r.uniform(2, 4), bump=False),
            (0, 0, h + t / 2))
        box("wall_n", (w, t, h), m.make("wall_n", scale=r.uniform(4, 8)), (0, d / 2 + t / 2, h / 2))
        box("wall_s", (w, t, h), m.make("wall_s", scale=r.uniform(4, 8)), (0, -d / 2 - t / 2, h / 2))
        box("wall_e", (t, d, h), m.make("wall_e", scale=r.uniform(4, 8)), (w / 2 + t / 2, 0, h / 2))
        box("wall_w", (t, d, h), m.make("wall_w", scale=r.uniform(4, 8)), (-w / 2 - t / 2, 0, h / 2))
        # a skirting board and a rug break the floor/wall lines
        box("skirting_n", (w, 0.02, 0.1), m.make("skirting", scale=20), (0, d / 2 - 0.01, 0.05))
        box("rug", (r.uniform(1.8, 2.4), r.uniform(1.2, 1.6), 0.01),
            m.make("rug", scale=r.uniform(6, 12)), (r.uniform(-0.3, 0.3), 0.6, 0.005),
            r.uniform(-0.2, 0.2))
        self._table()
        self._shelf()
        self._cabinet()
        self._pictures()
        self._boxes()
        self._lights()
        if not self.args.no_markers:
            self._markers()

    def _table(self):
        r, m = self.rng, self.mats
        x, y = r.uniform(-0.25, 0.25), r.uniform(0.7, 1.0)
        self.table_top = (x, y, 0.76)
        root = empty("table", (x, y, 0))
        root.rotation_euler = (0, 0, r.uniform(-0.15, 0.15))
        top = m.make("tabletop", scale=r.uniform(8, 14))
        leg = m.make("tableleg", scale=20)
        box("table_top", (1.4, 0.8, 0.04), top, (0, 0, 0.74), parent=root)
        for sx in (-1, 1):
            for sy in (-1, 1):
                box("table_leg", (0.05, 0.05, 0.72), leg, (sx * 0.64, sy * 0.34, 0.36), parent=root)
        # small things on the table
        for k in range(r.randint(4, 7)):
            sz = (r.uniform(0.06, 0.25), r.uniform(0.06, 0.2), r.uniform(0.03, 0.25))
            box(f"table_item{k}", sz, m.make("item", scale=r.uniform(15, 40)),
                (r.uniform(-0.6, 0.6), r.uniform(-0.3, 0.3), 0.76 + sz[2] / 2),
                r.uniform(0, 3.14), parent=root)

    def _shelf(self):
        """A bookshelf against the north wall, full of books of random sizes/colours."""
        r, m = self.rng, self.mats
        d = ROOM[1]
        x = r.uniform(-2.2, -1.4)
        root = empty("shelf", (x, d / 2 - 0.18, 0))
        frame = m.make("shelf", scale=12)
        width, height, depth = 1.2, 2.0, 0.32
        box("shelf_side", (0.03, depth, height), frame, (-width / 2, 0, height / 2), parent=root)
        box("shelf_side", (0.03, depth, height), frame, (width / 2, 0, height / 2), parent=root)
        box("shelf_back", (width, 0.02, height), frame, (0, depth / 2, height / 2), parent=root)
        book_mats = [m.make("book", scale=r.uniform(20, 60), bump=False) for _ in range(8)]
        levels = 5
        for lv in range(levels + 1):
            z = 0.05 + lv * (height - 0.1) / levels
            box("shelf_board", (width, depth, 0.025), frame, (0, 0, z), parent=root)
            if lv == levels:
                break
            cx = -width / 2 + 0.03
            while True:
                bw = r.uniform(0.02, 0.07)
                if cx + bw > width / 2 - 0.05:
                    break
                if r.random() < 0.1:  # a gap
                    cx += r.uniform(0.05, 0.15)
                    continue
                bh = r.uniform(0.16, 0.32)
                bd = r.uniform(0.18, 0.26)
                box("book", (bw, bd, bh), r.choice(book_mats),
                    (cx + bw / 2, 0.02, z + 0.0125 + bh / 2), parent=root)
                cx += bw + 0.003

    def _cabinet(self):
        r, m = self.rng, self.mats
        d = ROOM[1]
        x = r.uniform(1.3, 2.0)
        root = empty("cabinet", (x, d / 2 - 0.25, 0))
        body = m.make("cabinet", scale=r.uniform(6, 12))
        box("cabinet_body", (1.0, 0.45, 0.9), body, (0, 0, 0.45), parent=root)
        fronts = m.make("drawer", scale=r.uniform(10, 20))
        for row in range(3):
            box("drawer", (0.9, 0.02, 0.24), fronts, (0, -0.235, 0.15 + row * 0.29), parent=root)
            box("handle", (0.2, 0.03, 0.02), self.mats.plain("metal", (0.7, 0.7, 0.7, 1), 0.2),
                (0, -0.255, 0.22 + row * 0.29), parent=root)
        self.cabinet_top = (x, d / 2 - 0.25, 0.9)

    def _pictures(self):
        """Framed procedural 'paintings' on the north, east and west walls."""
        r, m = self.rng, self.mats
        w, d, _ = ROOM
        spots = [("n", r.uniform(-0.6, 0.6), r.uniform(1.5, 1.9)),
                 ("n", r.uniform(0.9, 2.2), r.uniform(1.5, 2.0)),
                 ("e", r.uniform(-1.5, 1.5), r.uniform(1.2, 1.8)),
                 ("w", r.uniform(-1.5, 0.5), r.uniform(1.2, 1.8))]
        for k, (wall, u, z) in enumerate(spots):
            pw, ph = r.uniform(0.5, 0.9), r.uniform(0.4, 0.7)
            frame = m.plain(f"frame{k}", hsv(r.random(), 0.3, r.choice((0.1, 0.9))), 0.4)
            art = m.make(f"art{k}", scale=r.uniform(10, 25))
            if wall == "n":
                loc, size, face, rot = (u, d / 2 - 0.015, z), (pw + 0.06, 0.03, ph + 0.06), (0, -0.016, 0), 0
            elif wall == "e":
                loc, size, face, rot = (w / 2 - 0.015, u, z), (0.03, pw + 0.06, ph + 0.06), (-0.016, 0, 0), 0
            else:
                loc, size, face, rot = (-w / 2 + 0.015, u, z), (0.03, pw + 0.06, ph + 0.06), (0.016, 0, 0), 0
            root = empty(f"picture{k}", loc)
            box("picture_frame", size, frame, (0, 0, 0), rot, parent=root)
            inner = tuple(s - 0.06 if s > 0.05 else 0.004 for s in size)
            box("picture_art", inner, art, face, rot, parent=root)

    def _boxes(self):
        """Four boxes that the `rearranged` variant moves; static elsewhere."""
        r, m = self.rng, self.mats
        tx, ty, tz = self.table_top
        places = {
            "box_a": (r.uniform(-1.3, -0.9), r.uniform(0.0, 0.4), 0.0),
            "box_b": (tx + r.uniform(-0.45, -0.2), ty + r.uniform(-0.1, 0.1), tz),
            "box_c": (r.uniform(0.9, 1.3), r.uniform(0.1, 0.5), 0.0),
            "box_d": (self.cabinet_top[0] + r.uniform(-0.2, 0.2), self.cabinet_top[1], 0.9),
        }
        for name, (x, y, z) in places.items():
            size = (r.uniform(0.25, 0.45), r.uniform(0.22, 0.4), r.uniform(0.18, 0.4))
            ob = box(name, size, m.make(name, scale=r.uniform(12, 25)),
                     (x, y, z + size[2] / 2), r.uniform(-0.5, 0.5))
            self.movable[name] = ob

    def _lights(self):
        r = self.rng
        w, d, h = ROOM
        world = bpy.data.worlds.new("world")
        world.use_nodes = True
        world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.6, 0.62, 0.7, 1)
        world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.25
        bpy.context.scene.world = world
        for k, (x, y) in enumerate([(r.uniform(-1.6, -0.8), r.uniform(-0.5, 1.2)),
                                    (r.uniform(0.8, 1.6), r.uniform(-0.5, 1.2)),
                                    (r.uniform(-0.5, 0.5), r.uniform(-1.8, -1.2))]):
            light = bpy.data.lights.new(f"ceiling_light{k}", "AREA")
            light.shape = "RECTANGLE"
            light.size, light.size_y = r.uniform(0.6, 1.2), r.uniform(0.3, 0.6)
            light.energy = r.uniform(120, 180)
            light.color = hsv(r.uniform(0.05, 0.15), r.uniform(0.0, 0.25), 1.0)[:3]
            ob = bpy.data.objects.new(f"ceiling_light{k}", light)
            ob.location = (x, y, h - 0.02)
            bpy.context.scene.collection.objects.link(ob)
        # a warm "window" on the west wall, lighting the room from the side
        light = bpy.data.lights.new("window", "AREA")
        light.shape = "RECTANGLE"
        light.size, light.size_y = 1.2, 1.0
        light.energy = r.uniform(100, 170)
        light.color = (1.0, 0.85, 0.7)
        ob = bpy.data.objects.new("window", light)
        ob.location = (-w / 2 + 0.05, r.uniform(-1.0, 1.0), 1.5)
        ob.rotation_euler = (0, math.radians(90), 0)  # -Z (emission) towards +x
        bpy.context.scene.collection.objects.link(ob)

    def _markers(self):
        """Small magenta emissive spheres at known world points (projection check)."""
        tx, ty, tz = self.table_top
        w, d, _ = ROOM
        mat = emission_material("marker", (1.0, 0.0, 1.0, 1.0), 8.0)
        points = [(-0.35 + tx * 0.5, d / 2 - 0.03, 1.15),
                  (0.7, d / 2 - 0.03, 0.45),
                  (tx + 0.5, ty - 0.3, tz + 0.02),
                  (-0.9, d / 2 - 0.03, 2.2),
                  (w / 2 - 0.03, 0.9, 1.05)]
        for k, p in enumerate(points):
            sphere(f"marker{k}", 0.015, mat, p)
            self.markers.append(p)


# ----------------------------------------------------------------------------- motion

def look_at(position, target, roll=0.0):
    """Blender camera rotation (looks down local -Z, +Y up) at `position` towards
    `target`, world z up, then rolled by `roll` radians about the viewing axis."""
    f = (Vector(target) - Vector(position)).normalized()
    right = f.cross(Vector((0, 0, 1))).normalized()
    up = right.cross(f)
    m = Matrix((right, up, -f)).transposed()  # columns: camera x, y, z in world
    return (m @ Matrix.Rotation(roll, 3, "Z")).to_quaternion()


class Jitter:
    """Hand-held shake: a sum of three sinusoids per axis with seeded frequencies/phases."""

    def __init__(self, rng, amp):
        self.amp = amp
        self.terms = [[(rng.uniform(0.7, 4.5), rng.uniform(0, 2 * math.pi)) for _ in range(3)]
                      for _ in range(3)]

    def __call__(self, t):
        return Vector([self.amp * sum(math.sin(2 * math.pi * f * t + p) for f, p in axis) / 3
                       for axis in self.terms])


def smoothstep(a, b, x):
    if x <= a:
        return 0.0
    if x >= b:
        return 1.0
    s = (x - a) / (b - a)
    return s * s * (3 - 2 * s)


class CameraPath:
    def __init__(self, rng, variant, target):
        self.variant = variant
        self.target = Vector(target)
        self.pos_jitter = Jitter(rng, 0.004)
        self.rot_jitter = Jitter(rng, math.radians(0.3))
        self.phase = rng.uniform(-0.3, 0.3)

    def pose(self, t):
        """(location, Blender quaternion) at time t seconds."""
        if self.variant == "dominant":
            c = Vector((0.0, -1.75, 1.3))
            pos = c + Vector((0.15 * math.sin(2 * math.pi * t / 5.3 + 0.4 + self.phase),
                              0.05 * math.sin(2 * math.pi * t / 6.1 + 1.1),
                              0.06 * math.sin(2 * math.pi * t / 4.1 + 0.2)))
            target = Vector((0.0, 1.5, 1.0))
        else:
            # orbit about the table: ~60 degrees of azimuth in 5 s, moving from t = 0
            az = math.radians(32) * math.sin(2 * math.pi * t / 10.0 - math.pi / 3 + self.phase)
            el = math.radians(17) + math.radians(5) * math.sin(2 * math.pi * t / 5.0)
            radius = 2.9 + 0.15 * math.sin(2 * math.pi * t / 6.3 + 0.8)
            target = self.target
            pos = target + radius * Vector((math.sin(az) * math.cos(el),
                                            -math.cos(az) * math.cos(el), math.sin(el)))
        pos = pos + self.pos_jitter(t)
        j = self.rot_jitter(t)
        q = look_at(pos, target, roll=j.z)
        q = q @ Quaternion((1, 0, 0), j.x) @ Quaternion((0, 1, 0), j.y)
        return pos, q


class Animator:
    """Keyframes objects every frame from functions of time; records moving intervals so
    that the object index (mask) marks an object from its first movement on."""

    def __init__(self, frames, fps):
        self.frames, self.fps = frames, fps
        self.tracks = {}  # name -> (object, function t -> (loc, quat, visible))

    def add(self, ob, fn, mask=True):
        """`mask`: this object (with its children) sets the object index; False for
        parts of an object that is already tracked (a figure's legs)."""
        ob.rotation_mode = "QUATERNION"
        self.tracks[ob.name] = (ob, fn, mask)

    def bake(self):
        events = {}
        for name, (ob, fn, mask) in self.tracks.items():
            prev = None
            first_move = -1
            prev_q = None
            for i in range(self.frames):
                loc, q, vis = fn(i / self.fps)
                if prev_q is not None and prev_q.dot(q) < 0:
                    q = -q  # keep quaternion keys on one hemisphere for interpolation
                prev_q = q
                state = (tuple(round(v, 7) for v in loc), tuple(round(v, 7) for v in q), vis)
                if prev is not None and state != prev and first_move < 0:
                    first_move = i
                prev = state
                ob.location = loc
                ob.rotation_quaternion = q
                ob.keyframe_insert("location", frame=i)
                ob.keyframe_insert("rotation_quaternion", frame=i)
                ob.hide_render = not vis
                ob.keyframe_insert("hide_render", frame=i)
            if not mask:
                continue
            events[name] = first_move
            for i in (0, first_move) if first_move > 0 else (0,):
                index = MOVING_INDEX if (first_move == 0 or i == first_move) else 0
                for child in [ob] + list(ob.children_recursive):
                    child.pass_index = index
                    child.keyframe_insert("pass_index", frame=i)
        return events


def static_track(ob):
    loc, q = ob.location.copy(), ob.rotation_euler.to_quaternion()
    return lambda t: (loc, q, True)


def move_track(ob, moves, hide_at=None):
    """Stay, then for each (t0, t1, dxyz, dyaw_deg, lift) glide to the new pose."""
    loc0, yaw0 = ob.location.copy(), ob.rotation_euler.z

    def fn(t):
        loc, yaw = loc0.copy(), yaw0
        for t0, t1, dxyz, dyaw, lift in moves:
            s = smoothstep(t0, t1, t)
            loc += s * Vector(dxyz)
            loc.z += lift * math.sin(math.pi * s)
            yaw += s * math.radians(dyaw)
        return loc, Quaternion((0, 0, 1), yaw), hide_at is None or t < hide_at
    return fn


def person(name, mats, rng, height):
    """A people-sized figure: torso, head, arms and two swinging legs (children of an
    empty at floor level). Returns the root and the two legs."""
    root = empty(name)
    clothes = mats.make(name + "_clothes", scale=rng.uniform(12, 25))
    trousers = mats.make(name + "_legs", scale=rng.uniform(15, 30))
    skin = mats.make(name + "_head", scale=30, contrast=0.6)
    s = height / 1.75
    box(name + "_torso", (0.46 * s, 0.26 * s, 0.62 * s), clothes, (0, 0, 1.2 * s), parent=root)
    sphere(name + "_head", 0.12 * s, skin, (0, 0, 1.64 * s), parent=root, segments=24)
    for side in (-1, 1):
        box(name + "_arm", (0.1 * s, 0.12 * s, 0.6 * s), clothes,
            (side * 0.29 * s, 0, 1.2 * s), parent=root)
    legs = []
    for side in (-1, 1):
        hip = empty(name + "_hip")
        hip.parent = root
        hip.location = (side * 0.12 * s, 0, 0.9 * s)
        box(name + "_leg", (0.16 * s, 0.18 * s, 0.88 * s), trousers, (0, 0, -0.44 * s), parent=hip)
        legs.append(hip)
    return root, legs


def walk_track(start, end, t0, t1, leg=None, phase=0.0):
    start, end = Vector(start), Vector(end)
    heading = math.atan2(end.y - start.y, end.x - start.x) + math.pi / 2  # face walking dir

    def fn(t):
        s = min(max((t - t0) / (t1 - t0), 0.0), 1.0)
        loc = start.lerp(end, s)
        loc.z += 0.02 * abs(math.sin(2 * math.pi * 0.9 * t))  # bob
        q = Quaternion((0, 0, 1), heading)
        if leg is not None:
            walking = 0.0 < s < 1.0
            swing = math.radians(22) * math.sin(2 * math.pi * 0.9 * t + phase) if walking else 0
            return Vector(leg.location), Quaternion((1, 0, 0), swing), True
        return loc, q, True
    return fn


# ----------------------------------------------------------------------------- render

def configure_render(scene, args, out):
    scene.render.resolution_x = args.width
    scene.render.resolution_y = args.height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    scene.render.fps = int(round(args.fps))
    scene.render.fps_base = scene.render.fps / args.fps
    scene.render.threads_mode = "FIXED"
    scene.render.threads = args.threads
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.color_depth = "8"
    scene.render.image_settings.compression = 15
    scene.render.use_motion_blur = args.motion_blur
    scene.render.motion_blur_shutter = 0.5
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.render.film_transparent = False
    if args.engine == "cycles":
        scene.render.engine = "CYCLES"
        cy = scene.cycles
        cy.device = "CPU"
        cy.samples = args.samples
        cy.use_adaptive_sampling = False
        cy.use_denoising = False
        if args.denoise:
            cy.use_denoising = True
            cy.denoiser = "OPENIMAGEDENOISE"
        cy.max_bounces = 3
        cy.diffuse_bounces = 2
        cy.glossy_bounces = 1
        cy.transmission_bounces = 0
        cy.volume_bounces = 0
        cy.transparent_max_bounces = 0
        cy.caustics_reflective = cy.caustics_refractive = False
        cy.sample_clamp_indirect = 5.0
        cy.use_animated_seed = True
        cy.filter_width = 1.5  # Blackman-Harris pixel filter: the anti-aliasing
        scene.view_layers[0].use_pass_object_index = True
        setup_mask_output(scene, out)
    else:
        scene.render.engine = "BLENDER_EEVEE"
        ee = scene.eevee
        ee.taa_render_samples = args.samples
        ee.use_soft_shadows = True
        ee.shadow_cube_size = "512"
        ee.shadow_cascade_size = "1024"
        ee.use_gtao = False
        ee.use_motion_blur = args.motion_blur
        ee.motion_blur_shutter = 0.5


def setup_mask_output(scene, out):
    """Compositor: object index == MOVING_INDEX -> mask/NNNNNN.png (0/255)."""
    scene.use_nodes = True
    nt = scene.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    rl = nt.nodes.new("CompositorNodeRLayers")
    comp = nt.nodes.new("CompositorNodeComposite")
    nt.links.new(rl.outputs["Image"], comp.inputs["Image"])
    idm = nt.nodes.new("CompositorNodeIDMask")
    idm.index = MOVING_INDEX
    idm.use_antialiasing = False
    nt.links.new(rl.outputs["IndexOB"], idm.inputs["ID value"])
    fo = nt.nodes.new("CompositorNodeOutputFile")
    fo.base_path = os.path.join(out, "mask")
    fo.format.file_format = "PNG"
    fo.format.color_mode = "BW"
    fo.format.color_depth = "8"
    fo.file_slots[0].path = "######"
    nt.links.new(idm.outputs["Alpha"], fo.inputs[0])


def make_camera(scene, args):
    cam_data = bpy.data.cameras.new("camera")
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.sensor_width = 36.0
    cam_data.lens_unit = "MILLIMETERS"
    cam_data.lens = args.fx * cam_data.sensor_width / args.width
    cam_data.shift_x = cam_data.shift_y = 0.0
    cam_data.clip_start, cam_data.clip_end = 0.05, 50.0
    cam = bpy.data.objects.new("camera", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return cam


def intrinsics(cam, args):
    """Pinhole intrinsics of the Blender camera as rdslam's camera.yaml (pixel centres at
    integer coordinates)."""
    d = cam.data
    fx = d.lens * args.width / d.sensor_width
    return {"width": args.width, "height": args.height, "fx": fx, "fy": fx,
            "cx": (args.width - 1) / 2.0, "cy": (args.height - 1) / 2.0}


BLENDER_TO_OPENCV = Matrix(((1, 0, 0, 0), (0, -1, 0, 0), (0, 0, -1, 0), (0, 0, 0, 1)))


def tum_pose(m_world_blendercam):
    m = m_world_blendercam @ BLENDER_TO_OPENCV
    t = m.to_translation()
    q = m.to_quaternion()
    if q.w < 0:
        q = -q
    return (t.x, t.y, t.z, q.x, q.y, q.z, q.w)


# ----------------------------------------------------------------------------- variants

def build_variant(args, rng, room, anim):
    """Moving objects of the variant; returns the descriptions for scene.json."""
    fps = args.fps
    info = {}
    if args.scene == "walking":
        # two figures crossing between the camera and the furniture, in opposite directions
        # and at different distances (about 1.2-2.5 m from the camera)
        for k, (y, x0, x1, t0, t1) in enumerate([
                (rng.uniform(-0.9, -0.6), -3.2, 3.2, 0.5, 4.5),
                (rng.uniform(-0.1, 0.3), 3.2, -3.2, 1.3, 5.3)]):
            h = rng.uniform(1.65, 1.9)
            root, legs = person(f"person{k}", room.mats, rng, h)
            anim.add(root, walk_track((x0, y, 0), (x1, y, 0), t0, t1))
            for j, leg in enumerate(legs):
                anim.add(leg, walk_track((x0, y, 0), (x1, y, 0), t0, t1, leg, math.pi * j),
                         mask=False)
            info[root.name] = {"height_m": h, "path": [[x0, y], [x1, y]], "seconds": [t0, t1]}
    elif args.scene == "rearranged":
        mv = room.movable
        plans = {
            "box_a": ([(1.2, 2.0, (0.45, 0.15, 0.0), 30, 0.0)], None),
            "box_b": ([(2.3, 3.1, (-0.5, -0.6, -0.76), -20, 0.25)], None),
            "box_c": ([], 3.5),
            "box_d": ([(3.8, 4.5, (-0.35, 0.0, 0.0), 45, 0.0)], None),
        }
        for name, (moves, hide) in plans.items():
            anim.add(mv[name], move_track(mv[name], moves, hide))
            info[name] = {"moves": [[m[0], m[1], list(m[2]), m[3]] for m in moves],
                          "removed_at_s": hide}
    elif args.scene == "dominant":
        m = room.mats
        root = empty("panel", (0.0, -0.45, 0.0))
        face = m.make("panel_face", scale=rng.uniform(14, 22), contrast=1.0)
        w, h = rng.uniform(1.1, 1.3), rng.uniform(0.85, 0.95)
        box("panel_board", (w, 0.025, h), face, (0, 0, 1.22), parent=root)
        stand = m.plain("panel_stand", (0.05, 0.05, 0.05, 1), 0.5)
        for side in (-1, 1):
            box("panel_leg", (0.03, 0.03, 1.22 - h / 2), stand,
                (side * w * 0.4, 0.02, (1.22 - h / 2) / 2), parent=root)
        loc0 = root.location.copy()

        def slide(t):
            dx = 0.5 * smoothstep(1.0, 3.0, t) - 0.8 * smoothstep(3.2, 5.0, t)
            return loc0 + Vector((dx, 0, 0)), Quaternion(), True
        anim.add(root, slide)
        info["panel"] = {"size_m": [w, h], "static_until_s": 1.0,
                         "slide_m": "+0.5 over 1.0-3.0 s, then -0.8 over 3.2-5.0 s"}
    for name, ob in room.movable.items():
        if name not in anim.tracks:
            anim.add(ob, static_track(ob))
    return info


# ----------------------------------------------------------------------------- main

def main():
    args = parse_args()
    out = os.path.abspath(args.out)
    if args.first == 0 and os.path.isdir(out) and os.listdir(out):
        sys.exit(f"render_room.py: {out} exists and is not empty")
    os.makedirs(os.path.join(out, "rgb"), exist_ok=True)
    rng = random.Random(args.seed)  # the room depends on the seed only, not on the variant

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    contrast = 0.35 if args.scene == "dominant" else 1.0
    mats = MaterialFactory(rng, contrast)
    room = Room(rng, mats, args)
    room.build()
    anim = Animator(args.frames, args.fps)
    variant_info = build_variant(args, random.Random(args.seed * 7919 + 17), room, anim)

    cam = make_camera(scene, args)
    path = CameraPath(random.Random(args.seed * 104729 + 3), args.scene,
                      (room.table_top[0], room.table_top[1], 0.8))
    anim.add(cam, lambda t: path.pose(t) + (True,), mask=False)
    events = anim.bake()
    events.pop("camera", None)
    scene.frame_start, scene.frame_end = 0, args.frames - 1
    configure_render(scene, args, out)
    if args.save_blend:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.save_blend))

    K = intrinsics(cam, args)
    with open(os.path.join(out, "camera.yaml"), "w") as f:
        f.write("# Blender camera: sensor width 36 mm fitted horizontally, lens %.6f mm\n"
                % cam.data.lens)
        f.write("model: pinhole-radtan\n")
        for k in ("width", "height", "fx", "fy", "cx", "cy"):
            f.write(f"{k}: {K[k]:.6f}\n" if isinstance(K[k], float) else f"{k}: {K[k]}\n")
    with open(os.path.join(out, "markers.txt"), "w") as f:
        f.write("# name x y z (world, metres): centres of the magenta marker spheres\n")
        for k, p in enumerate(room.markers):
            f.write(f"marker{k} {p[0]:.6f} {p[1]:.6f} {p[2]:.6f}\n")

    moving = [n for n in anim.tracks if n != "camera"]
    stamps, gt_lines, rgb_lines, obj_lines, times = [], [], [], [], []
    for i in range(args.frames):
        scene.frame_set(i)
        stamp = f"{i / args.fps:.9f}"
        gt_lines.append(stamp + " " + " ".join(f"{v:.9f}" for v in tum_pose(cam.matrix_world)))
        rgb_lines.append(f"{stamp} rgb/{i:06d}.png")
        for n in moving:
            ob = bpy.data.objects[n]
            mw = ob.matrix_world
            t, q = mw.to_translation(), mw.to_quaternion()
            obj_lines.append(f"{stamp} {n} {t.x:.6f} {t.y:.6f} {t.z:.6f} {q.x:.6f} {q.y:.6f} "
                             f"{q.z:.6f} {q.w:.6f} {int(not ob.hide_render)}")
        if i < args.first:
            continue
        scene.render.filepath = os.path.join(out, "rgb", f"{i:06d}.png")
        w0, c0 = time.time(), time.process_time()
        bpy.ops.render.render(write_still=True)
        times.append((time.time() - w0, time.process_time() - c0))
        print(f"render_room: frame {i + 1}/{args.frames} {times[-1][0]:.2f} s wall "
              f"{times[-1][1]:.2f} s cpu", flush=True)

    with open(os.path.join(out, "rgb.txt"), "w") as f:
        f.write(f"# rgb images rendered by tools/blender/render_room.py --scene {args.scene} "
                f"--seed {args.seed}\n# timestamp filename\n")
        f.write("\n".join(rgb_lines) + "\n")
    with open(os.path.join(out, "groundtruth.txt"), "w") as f:
        f.write("# T_world_cam, OpenCV camera (x right, y down, z forward), world z up\n"
                "# timestamp tx ty tz qx qy qz qw\n")
        f.write("\n".join(gt_lines) + "\n")
    with open(os.path.join(out, "objects.txt"), "w") as f:
        f.write("# timestamp name tx ty tz qx qy qz qw visible (T_world_obj, Blender object)\n")
        f.write("\n".join(obj_lines) + "\n")
    walls = sorted(t[0] for t in times)
    cpus = sorted(t[1] for t in times)
    summary = {
        "args": vars(args), "blender": bpy.app.version_string, "camera": K,
        "lens_mm": cam.data.lens, "variant": variant_info,
        "first_moving_frame": events,
        "render_seconds_per_frame": {
            "frames": len(times),
            "wall_median": walls[len(walls) // 2] if walls else None,
            "wall_max": walls[-1] if walls else None,
            "cpu_median": cpus[len(cpus) // 2] if cpus else None},
    }
    with open(os.path.join(out, "scene.json"), "w") as f:
        json.dump(summary, f, indent=2, default=str)
    print("render_room: done,", json.dumps(summary["render_seconds_per_frame"]), flush=True)


if __name__ == "__main__":
    main()

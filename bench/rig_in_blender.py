#!/usr/bin/python3
"""A setlight rig in Blender: the USD imported (or, without USD, the same lights
built from rig.json in bpy) and rendered with Cycles against `setlight render --rig`.

    /usr/bin/python3 bench/rig_in_blender.py [--res 128] [--spp 256] [--energy 0.99]
        [--work /tmp/setlight-bench/rig] [--setlight build/setlight] [--blender blender]

The same file is the Blender side: the driver runs
`blender -b --factory-startup --python bench/rig_in_blender.py -- --side ...`.

1. Probe: Blender's version and whether it can import USD
   (`bpy.app.build_options.usd` and the `bpy.ops.wm.usd_import` operator). Debian's
   Blender 3.4 is built without USD: the script says so and falls back to building the
   rig's lights from rig.json in bpy, which makes the run an independent check of the
   rig's radiometry in a second renderer.
2. Units, checked rather than assumed, each against setlight's render of the same rig:
   `rect`: a uniform rect light (radiance 3, 2, 1) seen head-on by an orthographic
   camera (Blender area light, `visible_camera` on): pixel ratio Blender / setlight per
   channel; `textured`: the same rect with a 4 x 2 texture (mesh emitter, below): relative
   RMSE per pixel (a flipped or rotated texture is tens of %); `sun`: a distant light (10
   degrees, radiance 2, 1.5, 1) on a Lambert 0.5 plane facing it: pixel ratio.
3. The rig: `setlight simulate --scene stage --size small` (cached), `setlight rig
   truth/latlong.exr --energy E` (window textured, rects, disks as distant lights, the
   residual dome), then the grey sphere (Lambert 0.18, the `grey` preset's orthographic
   camera, pixel centres) rendered by Cycles and by `setlight render --rig`, and both
   under the original map (`--env`) as the dome-convention control. Each render is two
   seeds with half the samples each; the per-pixel noise (h1 - h2)^2 / 4 of both sides
   is taken out of the mean squared difference (systematic relative RMSE over the
   sphere, 1 px rim left out, over the reference's RMS as `setlight rig --validate`);
   the ratio of the mean pixel values is printed too. Also the chrome sphere (a mirror
   of reflectance 1; box-filtered pixels in both renderers, as a mirror at pixel centres
   puts each small bright light in a few pixels or none).

Conventions (docs/lightrig.md, "In Blender"): setlight (x, y, z), +Y up, maps to
Blender (z, x, y), +Z up (a rotation; Blender's equirectangular lookup of that vector
reads the texel setlight reads, bench/render_vs_cycles.py). Blender area light of power
P watts, area A: radiance P / (4 A) (measured by `rect`), so P = 4 A L; colour = L / Y(L)
and P from Y. Sun: strength = the irradiance at normal incidence of the rig's cone,
pi L sin^2(angle / 2) (checked by `sun`; strength pi L tan^2, Cycles' radiance
normalisation, left the plane 0.71% bright at 10 degrees). Rects at infinity go 10 km away sized by their angular size with the
radiance scaled to the rig's solid angle, as setlight's renderer places them. Blender's
area lights take no image through its Python API, so a textured rect becomes a mesh
quad with an Emission shader (strength 1 = radiance 1, checked by `textured`): texture
x radiance, column 0 at the light's +X (`axis_u`), row 0 at its +Y, nearest texel.
"""
import argparse
import json
import math
import os
import subprocess
import sys

try:
    import bpy  # noqa: F401
    IN_BLENDER = True
except ImportError:
    IN_BLENDER = False

HERE = os.path.abspath(__file__)
GREY_CAMERA = dict(position=[0, 0, -10], look_at=[0, 0, 0], up=[0, 1, 0], width=2.0)
RIG_FAR = 1e4


def luma(c):
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]


# ---------------------------------------------------------------- Blender side

def blender_main(argv):
    import bpy
    import mathutils
    ap = argparse.ArgumentParser()
    ap.add_argument("--side", required=True, help="probe | render")
    ap.add_argument("--rig")
    ap.add_argument("--usda")
    ap.add_argument("--env")
    ap.add_argument("--camera", help="JSON: position, look_at, up, width (setlight coordinates)")
    ap.add_argument("--object", default="sphere", help="sphere | plane | none")
    ap.add_argument("--albedo", type=float, default=0.18)
    ap.add_argument("--chrome", action="store_true", help="the sphere is a perfect mirror")
    ap.add_argument("--box", action="store_true", help="box pixel filter (else pixel centres)")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out")
    a = ap.parse_args(argv)
    if a.side == "probe":
        try:
            bpy.ops.wm.usd_import.get_rna_type()
            op = True
        except (KeyError, AttributeError):
            op = False
        print("PROBE " + json.dumps({"version": bpy.app.version_string,
                                     "build_usd": bool(getattr(bpy.app.build_options, "usd", False)),
                                     "usd_import": op}), flush=True)
        return
    sc = bpy.context.scene
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o, do_unlink=True)
    # setlight (x, y, z) -> Blender (z, x, y); after a USD import (Y-up stage turned
    # Z-up by the importer) -> (x, -z, y)
    usd = bool(a.usda)

    def v(p):
        return mathutils.Vector((p[0], -p[2], p[1]) if usd else (p[2], p[0], p[1]))

    def frame(obj, origin, x_axis, y_axis, z_axis):
        m = mathutils.Matrix.Identity(4)
        for r in range(3):
            m[r][0], m[r][1], m[r][2], m[r][3] = x_axis[r], y_axis[r], z_axis[r], origin[r]
        obj.matrix_world = m

    def diffuse(name, albedo):
        m = bpy.data.materials.new(name)
        m.use_nodes = True
        nt = m.node_tree
        nt.nodes.clear()
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        s = nt.nodes.new("ShaderNodeBsdfDiffuse")
        s.inputs["Color"].default_value = (albedo, albedo, albedo, 1)
        s.inputs["Roughness"].default_value = 0
        nt.links.new(s.outputs[0], out.inputs["Surface"])
        return m

    # camera: orthographic, looking from position to look_at
    cam = json.loads(a.camera)
    pos, look, up = v(cam["position"]), v(cam["look_at"]), v(cam["up"])
    fwd = (look - pos).normalized()
    right = fwd.cross(up).normalized()
    cd = bpy.data.cameras.new("cam")
    cd.type = "ORTHO"
    cd.ortho_scale = cam["width"]
    cd.clip_start, cd.clip_end = 0.01, 1e6
    co = bpy.data.objects.new("cam", cd)
    sc.collection.objects.link(co)
    frame(co, pos, right, right.cross(fwd), -fwd)
    sc.camera = co

    # world: the rig's dome or the map (both setlight lat-longs)
    w = bpy.data.worlds.new("world")
    sc.world = w
    w.use_nodes = True
    nt = w.node_tree
    nt.nodes.clear()
    bg = nt.nodes.new("ShaderNodeBackground")
    nt.links.new(bg.outputs[0], nt.nodes.new("ShaderNodeOutputWorld").inputs["Surface"])
    rig = json.load(open(a.rig)) if a.rig else None
    rig_dir = os.path.dirname(os.path.abspath(a.rig)) if a.rig else ""
    env = a.env or (os.path.join(rig_dir, rig["dome"]["file"]) if rig and rig["dome"]["file"] else None)
    if env:
        img = bpy.data.images.load(env)
        img.colorspace_settings.name = "Linear"
        tex = nt.nodes.new("ShaderNodeTexEnvironment")
        tex.image = img
        tex.interpolation = "Closest"  # setlight's dome is piecewise constant per texel
        if usd:
            # the importer's frame is ours turned -90 degrees about Z
            tc = nt.nodes.new("ShaderNodeTexCoord")
            mp = nt.nodes.new("ShaderNodeMapping")
            mp.vector_type = "VECTOR"
            mp.inputs["Rotation"].default_value = (0, 0, math.pi / 2)
            nt.links.new(tc.outputs["Generated"], mp.inputs["Vector"])
            nt.links.new(mp.outputs["Vector"], tex.inputs["Vector"])
        nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
        bg.inputs["Strength"].default_value = 1
    else:
        bg.inputs["Strength"].default_value = 0

    if usd:
        bpy.ops.wm.usd_import(filepath=os.path.abspath(a.usda), import_lights=True)
    elif rig:
        for i, l in enumerate(rig["lights"]):
            build_light(bpy, mathutils, sc, v, frame, rig_dir, i, l)

    if a.object == "sphere":
        # an exact sphere: a one-point cloud (as the peers' cycles_scene.py)
        me = bpy.data.meshes.new("pt")
        me.from_pydata([(0.0, 0.0, 0.0)], [], [])
        ob = bpy.data.objects.new("sphere", me)
        sc.collection.objects.link(ob)
        mat = diffuse("grey", a.albedo)
        if a.chrome:
            # a mirror of reflectance 1 (Principled metallic, base 1: Schlick F = 1)
            nt = mat.node_tree
            nt.nodes.clear()
            p = nt.nodes.new("ShaderNodeBsdfPrincipled")
            p.inputs["Base Color"].default_value = (1, 1, 1, 1)
            p.inputs["Metallic"].default_value = 1
            p.inputs["Roughness"].default_value = 0
            nt.links.new(p.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
        ob.data.materials.append(mat)
        ng = bpy.data.node_groups.new("pts", "GeometryNodeTree")
        ng.inputs.new("NodeSocketGeometry", "Geometry")
        ng.outputs.new("NodeSocketGeometry", "Geometry")
        gi, go = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
        m2p = ng.nodes.new("GeometryNodeMeshToPoints")
        m2p.inputs["Radius"].default_value = 1.0
        sm = ng.nodes.new("GeometryNodeSetMaterial")
        sm.inputs["Material"].default_value = mat
        ng.links.new(gi.outputs[0], m2p.inputs["Mesh"])
        ng.links.new(m2p.outputs[0], sm.inputs["Geometry"])
        ng.links.new(sm.outputs[0], go.inputs[0])
        ob.modifiers.new("pts", "NODES").node_group = ng
    elif a.object == "plane":
        # a 2 x 2 plane through the origin, facing setlight's +Z
        me = bpy.data.meshes.new("plane")
        me.from_pydata([tuple(v(p)) for p in ([-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0])], [],
                       [(0, 1, 2, 3)])
        ob = bpy.data.objects.new("plane", me)
        sc.collection.objects.link(ob)
        ob.data.materials.append(diffuse("plane", a.albedo))

    r = sc.render
    r.engine = "CYCLES"
    r.resolution_x = r.resolution_y = a.res
    r.resolution_percentage = 100
    r.film_transparent = True
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.image_settings.color_mode = "RGBA"
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.look = "None"
    c = sc.cycles
    c.device = "CPU"
    c.samples = a.spp
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.seed = a.seed
    if a.box:
        # the pixel's area, as setlight's default box filter
        c.pixel_filter_type = "BOX"
        c.filter_width = 1.0
    else:
        c.pixel_filter_type = "BLACKMAN_HARRIS"
        c.filter_width = 0.01  # pixel centres, as setlight --pixel-centers
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    r.threads_mode = "FIXED"
    r.threads = 2
    bpy.ops.render.render(write_still=False)
    bpy.data.images["Render Result"].save_render(a.out)
    print("RENDERED " + a.out, flush=True)


def build_light(bpy, mathutils, sc, v, frame, rig_dir, i, l):
    d = l["direction"]
    rad = l["radiance"]
    au = l["axis_u"]
    av = [d[1] * au[2] - d[2] * au[1], d[2] * au[0] - d[0] * au[2], d[0] * au[1] - d[1] * au[0]]
    if l["type"] == "rect":
        if l["position"] is None:
            tu = math.tan(math.radians(l["angular_size"][0]) / 2)
            tv = math.tan(math.radians(l["angular_size"][1]) / 2)
            om = 4 * math.asin(tu * tv / math.sqrt((1 + tu * tu) * (1 + tv * tv)))
            rad = [c * l["solid_angle"] / om for c in rad]
            pos = [RIG_FAR * c for c in d]
            w, h = 2 * RIG_FAR * tu, 2 * RIG_FAR * tv
        else:
            pos, (w, h) = l["position"], l["size"]
            n = math.sqrt(sum(c * c for c in pos))
            d = [c / n for c in pos]
        X, Y, Z = v(au), v(av), v(d)
        if l["texture"]:
            # a mesh emitter: UV (0, 1) (the image's top left) at +X +Y
            corners = [(1, 1, 0, 1), (-1, 1, 1, 1), (-1, -1, 1, 0), (1, -1, 0, 0)]
            verts = [tuple(v(pos) + su * w / 2 * X + sv * h / 2 * Y) for su, sv, _, _ in corners]
            me = bpy.data.meshes.new("light_%02d" % (i + 1))
            me.from_pydata(verts, [], [(0, 1, 2, 3)])
            uv = me.uv_layers.new(name="UVMap")
            for k, (_, _, u, vv) in enumerate(corners):
                uv.data[k].uv = (u, vv)
            ob = bpy.data.objects.new(me.name, me)
            sc.collection.objects.link(ob)
            m = bpy.data.materials.new(me.name)
            m.use_nodes = True
            nt = m.node_tree
            nt.nodes.clear()
            img = bpy.data.images.load(os.path.join(rig_dir, l["texture"]))
            img.colorspace_settings.name = "Linear"
            tex = nt.nodes.new("ShaderNodeTexImage")
            tex.image = img
            tex.interpolation = "Closest"
            mul = nt.nodes.new("ShaderNodeVectorMath")
            mul.operation = "MULTIPLY"
            mul.inputs[1].default_value = rad
            em = nt.nodes.new("ShaderNodeEmission")
            em.inputs["Strength"].default_value = 1.0
            nt.links.new(tex.outputs["Color"], mul.inputs[0])
            nt.links.new(mul.outputs["Vector"], em.inputs["Color"])
            nt.links.new(em.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
            ob.data.materials.append(m)
            return
        ld = bpy.data.lights.new("light_%02d" % (i + 1), "AREA")
        ld.shape = "RECTANGLE"
        ld.size, ld.size_y = w, h
        y = luma(rad)
        ld.color = [c / y for c in rad]
        ld.energy = 4 * w * h * y  # radiance P / (4 A): see `rect`
        ob = bpy.data.objects.new(ld.name, ld)
        sc.collection.objects.link(ob)
        ob.visible_camera = True
        frame(ob, v(pos), X, Y, Z)  # emits along its -Z: toward the capture point
        return
    if l["position"] is not None:
        raise SystemExit("placed %s lights are not built by this bench" % l["type"])
    # at infinity: the cone of the rig's solid angle, as setlight's renderer
    half = math.acos(1 - l["solid_angle"] / (2 * math.pi))
    ld = bpy.data.lights.new("light_%02d" % (i + 1), "SUN")
    ld.angle = 2 * half
    y = luma(rad)
    ld.color = [c / y for c in rad]
    # Blender's sun strength is the irradiance it gives at normal incidence (W/m^2,
    # measured by `sun`), a uniform cone's pi L sin^2(half angle)
    ld.energy = y * math.pi * math.sin(half) ** 2
    ob = bpy.data.objects.new(ld.name, ld)
    sc.collection.objects.link(ob)
    Z = v(d)
    X = Z.orthogonal().normalized()
    frame(ob, v([0, 0, 0]), X, Z.cross(X), Z)


# ---------------------------------------------------------------- driver side

def run(cmd, **kw):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kw)
    if p.returncode != 0:
        raise SystemExit("failed (%d): %s\n%s" % (p.returncode, " ".join(cmd), p.stdout[-3000:]))
    return p.stdout


def blender(a, *args):
    return run([a.blender, "-b", "--factory-startup", "--python", HERE, "--"] + [str(x) for x in args])


def load(path):
    import cv2
    import numpy as np
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise SystemExit("cannot read " + path)
    return img[..., [2, 1, 0, 3]].astype(np.float64)


def main():
    os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
    import cv2
    import numpy as np
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spp", type=int, default=256, help="per render, split over two seeds")
    ap.add_argument("--energy", type=float, default=0.99)
    ap.add_argument("--spheres", default="grey,chrome", help="grey (Lambert 0.18, pixel centres), chrome (mirror, box-filtered pixels)")
    ap.add_argument("--work", default="/tmp/setlight-bench/rig")
    ap.add_argument("--setlight", default=os.path.join(os.path.dirname(HERE), "..", "build", "setlight"))
    ap.add_argument("--blender", default=os.environ.get("BLENDER", "blender"))
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    W = lambda *p: os.path.join(a.work, *p)  # noqa: E731

    out = blender(a, "--side", "probe")
    probe = json.loads([ln for ln in out.splitlines() if ln.startswith("PROBE ")][0][6:])
    use_usd = probe["build_usd"] and probe["usd_import"]
    if use_usd:
        print("Blender %s: imports USD (bpy.ops.wm.usd_import): the rig's USD is imported" % probe["version"])
    else:
        print("Blender %s: built without USD (bpy.app.build_options.usd is %s, the operator "
              "bpy.ops.wm.usd_import %s): the USD cannot be imported here; building the same lights "
              "from rig.json in bpy instead (an independent check of the rig's radiometry)" % (
                  probe["version"], probe["build_usd"],
                  "does not exist" if not probe["usd_import"] else "exists"))
    results = {"blender": probe["version"], "usd_import": use_usd, "res": a.res, "spp": a.spp}

    def both(name, rig=None, env=None, scene=None, camera=GREY_CAMERA, obj="sphere", albedo=0.18,
             res=a.res, spp=a.spp, usda=None, chrome=False):
        """Blender and setlight, two seeds each with half the samples."""
        imgs = {"blender": [], "setlight": []}
        for seed in (1, 2):
            p = W("%s_blender_s%d.exr" % (name, seed))
            args = ["--side", "render", "--camera", json.dumps(camera), "--object", obj, "--albedo", albedo,
                    "--res", res, "--spp", spp // 2, "--seed", seed, "--out", p]
            args += ["--rig", rig] if rig else []
            args += ["--env", env] if env else []
            args += ["--usda", usda] if usda else []
            # chrome: the pixel's area (a mirror at pixel centres puts each tiny bulb in a
            # few pixels or none, and the RMSE measures that)
            args += ["--chrome", "--box"] if chrome else []
            blender(a, *args)
            imgs["blender"].append(load(p))
            p = W("%s_setlight_s%d.exr" % (name, seed))
            cmd = [a.setlight, "render", "--quiet", "--scene", scene, "--width", str(res),
                   "--spp", str(spp // 2), "--seed", str(seed), "-o", p]
            cmd += [] if chrome else ["--pixel-centers"]
            cmd += ["--rig", rig] if rig else ["--env", env]
            cmd += ["--material", "conductor:1,1,1:0"] if chrome else []
            run(cmd)
            imgs["setlight"].append(load(p))
        return imgs

    def scene_file(name, objects, camera):
        p = W(name + "_scene.json")
        cam = dict(type="orthographic", aspect=1, **camera)
        json.dump({"objects": objects, "camera": cam,
                   "materials": {"m": {"type": "lambert", "color": [0.5, 0.5, 0.5]}}}, open(p, "w"))
        return p

    def rig_file(name, lights):
        p = W(name + "_rig.json")
        json.dump({"version": 2, "lights": lights, "dome": {"file": None}}, open(p, "w"))
        return p

    # --- 2. units
    head_on = dict(position=[0, 0, 0], look_at=[0, 0, 1], up=[0, 1, 0], width=2.0)
    rect = dict(type="rect", direction=[0, 0, 1], solid_angle=0.08, radiance=[3.0, 2.0, 1.0],
                integral=[0, 0, 0], position=[0, 0, 3], size=[1.2, 0.6], texture=None,
                axis_u=[1, 0, 0], angular_size=[22.6, 11.4])
    tex = np.array([[[1, 1, 1], [2, 1, 1], [3, 1, 1], [4, 1, 1]],
                    [[1, 1, 2], [1, 2, 2], [1, 3, 2], [1, 4, 2]]], np.float32)
    cv2.imwrite(W("unit_texture.exr"), tex[..., ::-1].copy())
    textured = dict(rect, texture="unit_texture.exr")
    sun = dict(type="distant", direction=[0, 0, 1], radiance=[2.0, 1.5, 1.0], integral=[0, 0, 0],
               solid_angle=2 * math.pi * (1 - math.cos(math.radians(5))), position=None, size=None,
               texture=None, axis_u=[1, 0, 0], angular_size=[10, 10])
    facing = dict(position=[0, 0, 5], look_at=[0, 0, 0], up=[0, 1, 0], width=2.4)
    units = {}
    # setlight's scenes need an object: a speck far out of view
    speck = [dict(type="sphere", center=[0, 100, 0], radius=0.01, material="m")]
    for name, light, obj, cam, objects in (
            ("rect", rect, "none", head_on, speck),
            ("textured", textured, "none", head_on, speck),
            ("sun", sun, "plane", facing, [dict(type="rect", center=[0, 0, 0], u=[1, 0, 0], v=[0, 1, 0],
                                                 material="m")])):
        imgs = both("unit_" + name, rig=rig_file("unit_" + name, [light]), obj=obj, albedo=0.5,
                    scene=scene_file("unit_" + name, objects, cam), camera=cam, res=64, spp=16)
        b = 0.5 * (imgs["blender"][0] + imgs["blender"][1])
        s = 0.5 * (imgs["setlight"][0] + imgs["setlight"][1])
        # the light's (or plane's) inside: lit in setlight, its 4 neighbours too
        lit = s[..., :3].sum(-1) > 0
        inner = lit.copy()
        inner[1:-1, 1:-1] &= lit[:-2, 1:-1] & lit[2:, 1:-1] & lit[1:-1, :-2] & lit[1:-1, 2:]
        inner[[0, -1], :] = inner[:, [0, -1]] = False
        ratio = [float(b[..., c][inner].mean() / s[..., c][inner].mean()) for c in range(3)]
        d = (b - s)[..., :3][inner]
        rr = float(np.sqrt(np.mean(d * d) / np.mean(s[..., :3][inner] ** 2)))
        units[name] = dict(ratio=ratio, rel_rmse=rr, pixels=int(inner.sum()))
        print("unit %-8s Blender / setlight per channel %.4f %.4f %.4f, relative RMSE %.4f%% (%d px)"
              % (name, ratio[0], ratio[1], ratio[2], 100 * rr, inner.sum()), flush=True)
    results["units"] = units

    # --- 3. the stage rig
    stage = W("stage")
    if not os.path.exists(os.path.join(stage, "truth", "latlong.exr")):
        run([a.setlight, "simulate", "--scene", "stage", "--size", "small", "--out", stage, "--quiet"])
    truth = os.path.join(stage, "truth", "latlong.exr")
    run([a.setlight, "rig", truth, "-o", W("RIG.usda"), "--json", W("rig.json"), "--energy", str(a.energy),
         "--quiet"])
    rig = json.load(open(W("rig.json")))
    kinds = {}
    for l in rig["lights"]:
        k = "textured rect" if l["texture"] else l["type"]
        kinds[k] = kinds.get(k, 0) + 1
    print("rig: %d lights (%s), dome %s" % (len(rig["lights"]),
                                            ", ".join("%d %s" % (n, k) for k, n in sorted(kinds.items())),
                                            rig["dome"]["file"]), flush=True)
    results["rig_lights"] = kinds
    n = a.res
    c = (np.arange(n) + 0.5) / n * 2 - 1
    mask = (c[None, :] ** 2 + c[:, None] ** 2) < (1 - 2.0 / n) ** 2  # sphere, 1 px rim left out

    def compare(b_imgs, s_imgs):
        """first against second (the reference), each two seeds"""
        b = 0.5 * (b_imgs[0] + b_imgs[1])[..., :3]
        s = 0.5 * (s_imgs[0] + s_imgs[1])[..., :3]
        vb = ((b_imgs[0] - b_imgs[1])[..., :3] ** 2 / 4)[mask]
        vs = ((s_imgs[0] - s_imgs[1])[..., :3] ** 2 / 4)[mask]
        d = (b - s)[mask]
        # over the reference's RMS, as sl_relative_rmse and `setlight rig --validate` (a
        # chrome sphere's mean is far below its RMS: its reflections of the lights dominate)
        ms = math.sqrt(float(np.mean(s[mask] ** 2)))
        mse = float(np.mean(d * d))
        return dict(rel_rmse=math.sqrt(mse) / ms,
                    systematic=math.sqrt(max(0.0, mse - float(np.mean(vb)) - float(np.mean(vs)))) / ms,
                    noise_first=math.sqrt(float(np.mean(vb))) / ms,
                    noise_second=math.sqrt(float(np.mean(vs))) / ms,
                    mean_ratio=float(np.mean(b[mask])) / float(np.mean(s[mask])))

    for sphere in a.spheres.split(","):
        rows = {}
        spp = a.spp
        for name, kw in (("map", dict(env=truth)),
                         ("rig", dict(rig=W("rig.json"), usda=W("RIG.usda") if use_usd else None))):
            imgs = both("%s_%s" % (sphere, name), scene="grey", chrome=sphere == "chrome", spp=spp, **kw)
            rows[name] = dict(imgs=imgs, **compare(imgs["blender"], imgs["setlight"]))
        # the rig against the map, within each renderer
        for r in ("blender", "setlight"):
            rows["rig_vs_map_" + r] = compare(rows["rig"]["imgs"][r], rows["map"]["imgs"][r])
        for k in rows:
            rows[k].pop("imgs", None)
            r = rows[k]
            what = {"map": "Blender / setlight, under the map", "rig": "Blender / setlight, under the rig",
                    "rig_vs_map_blender": "rig / map, in Blender",
                    "rig_vs_map_setlight": "rig / map, in setlight"}[k]
            print("%-6s %-34s relative RMSE %.3f%%, systematic %.3f%% (noise %.3f%%, %.3f%%), mean ratio %.4f"
                  % (sphere, what, 100 * r["rel_rmse"], 100 * r["systematic"], 100 * r["noise_first"],
                     100 * r["noise_second"], r["mean_ratio"]), flush=True)
        results[sphere] = dict(spp=spp, **rows)
    json.dump(results, open(W("results.json"), "w"), indent=1)
    print("results: " + W("results.json"))


if __name__ == "__main__":
    if IN_BLENDER:
        blender_main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
    else:
        main()

"""Mitsuba 3 reference radiosity at points of the Cornell box, for tests/reference.rs.

Reads assets/cornell_box.gltf (the built-in Cornell box as glTF) and the points in
tests/data/mitsuba_cornell_points.csv (x,y,z,nx,ny,nz), estimates at each point the radiance L
leaving it along its normal with Mitsuba's `path` integrator (`integrator.sample` on a ray
arriving down the normal, what a radiancemeter there would see; no depth limit, RGB,
one-sided diffuse surfaces and area lights, as our solver models them),
and writes tests/data/mitsuba_cornell.csv: x,y,z,nx,ny,nz,r,g,b,sr,sg,sb with the radiosity
B = pi * L and its 1-sigma standard error from independent renders.

The points are a sample of `radiosity bench builtin:cornell`'s probes (eight of each
class), less those in the 0.1 mm gap between the lamp and the ceiling, where the answer
depends on each renderer's ray offsets rather than on the light.

Run once, from the repository root (the test itself needs no Python; 25 s here):
    pip install mitsuba==3.9.1
    python3 tests/data/mitsuba_cornell.py
"""
import base64, csv, json, math, os, struct, tempfile
import mitsuba as mi

mi.set_variant("scalar_rgb")
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GLTF = os.path.join(ROOT, "assets", "cornell_box.gltf")
POINTS = os.path.join(ROOT, "tests", "data", "mitsuba_cornell_points.csv")
OUT = os.path.join(ROOT, "tests", "data", "mitsuba_cornell.csv")
SPP, RENDERS = 1 << 14, 16

gltf = json.load(open(GLTF))
buffers = [base64.b64decode(b["uri"].split(",", 1)[1]) for b in gltf["buffers"]]


def accessor(i):
    a = gltf["accessors"][i]
    view = gltf["bufferViews"][a["bufferView"]]
    data = buffers[view["buffer"]]
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    width = {"VEC3": 3, "SCALAR": 1}[a["type"]]
    fmt = {5126: "f", 5125: "I"}[a["componentType"]]
    n = a["count"] * width
    values = struct.unpack_from("<%d%s" % (n, fmt), data, start)
    return [values[k:k + width] for k in range(0, n, width)]


scene = {"type": "scene", "integrator": {"type": "path", "max_depth": -1}}
tmp = tempfile.mkdtemp()
for node in gltf["nodes"]:
    assert "matrix" not in node and "translation" not in node, "identity transforms only"
    mesh = gltf["meshes"][node["mesh"]]
    for k, prim in enumerate(mesh["primitives"]):
        pos = accessor(prim["attributes"]["POSITION"])
        idx = [i[0] for i in accessor(prim["indices"])]
        path = os.path.join(tmp, "%s_%d.obj" % (mesh["name"], k))
        with open(path, "w") as f:
            for p in pos:
                f.write("v %r %r %r\n" % p)
            for t in range(0, len(idx), 3):
                f.write("f %d %d %d\n" % (idx[t] + 1, idx[t + 1] + 1, idx[t + 2] + 1))
        mat = gltf["materials"][prim["material"]]
        rho = mat["pbrMetallicRoughness"]["baseColorFactor"][:3]
        shape = {"type": "obj", "filename": path, "face_normals": True,
                 "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": rho}}}
        if "emissiveFactor" in mat:
            s = mat.get("extensions", {}).get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": [c * s for c in mat["emissiveFactor"]]}}
        scene["%s_%d" % (mesh["name"], k)] = shape

points = [[float(v) for v in row] for row in list(csv.reader(open(POINTS)))[1:]]
s = mi.load_dict(scene)
integrator = s.integrator()
rows = []
for i, p in enumerate(points):
    x, y, z, nx, ny, nz = p
    d = 1e-5
    samples = []
    for seed in range(RENDERS):
        sampler = mi.load_dict({"type": "independent"})
        sampler.seed(1000 * i + seed)
        acc = [0.0, 0.0, 0.0]
        for _ in range(SPP):
            ray = mi.Ray3f(mi.Point3f(x + nx * d, y + ny * d, z + nz * d), mi.Vector3f(-nx, -ny, -nz))
            L, _, _ = integrator.sample(s, sampler, ray)
            for c in range(3):
                acc[c] += L[c]
            sampler.advance()
        samples.append([math.pi * a / SPP for a in acc])
    mean = [sum(v[c] for v in samples) / RENDERS for c in range(3)]
    var = [sum((v[c] - mean[c]) ** 2 for v in samples) / (RENDERS - 1) for c in range(3)]
    se = [math.sqrt(v / RENDERS) for v in var]
    rows.append(p + mean + se)
    print(i, p[:3], mean, se, flush=True)
with open(OUT, "w") as f:
    f.write("x,y,z,nx,ny,nz,r,g,b,sr,sg,sb\n")
    for r in rows:
        f.write(",".join(repr(v) for v in r) + "\n")

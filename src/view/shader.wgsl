// The 3D view: one vertex per element corner. The solution comes as the irradiance H in
// textures (per element for flat reconstruction, per display vertex for Gouraud, and per
// display vertex with its slopes for Hermite), so a new snapshot is a texture upload,
// never a vertex-buffer rebuild. The displayed
// radiosity is B = ρ(uv)·H + E(uv): with textures on, ρ(uv) = ρ_e · T_base(uv) / mean_e
// (ρ_e the element's reflectance as solved, mean_e the texture's mean over its triangle,
// which ρ_e already carries) and likewise E(uv); with textures off, B = ρ_e·H + E_e, the
// solution itself.

struct Uniforms {
    view_proj: mat4x4<f32>,
    // Multiplier from radiosity B (W/m²) to displayed radiance: 2^EV / π.
    exposure: f32,
    // 0 flat, 1 Gouraud, 2 Hermite (cubic Bézier triangles).
    recon: u32,
    // 0 clamp, 1 Reinhard, 2 ACES (Narkowicz fit), 3 AgX.
    tonemap: u32,
    // 1: false colour of log10 luminance of B over [log_lo, log_hi].
    false_colour: u32,
    wire: u32,
    // Selected object id, or 0xffffffff.
    selected: u32,
    // Width of the value textures.
    width: u32,
    log_lo: f32,
    log_hi: f32,
    // 1: show the textures under the light.
    textures: u32,
    pad1: f32,
    pad2: f32,
};

@group(0) @binding(0) var<uniform> u: Uniforms;
@group(0) @binding(1) var element_values: texture_2d<f32>;
@group(0) @binding(2) var vertex_values: texture_2d<f32>;
// Hermite: per display vertex its value and the gradient of each channel (12 floats in
// 3 texels).
@group(0) @binding(3) var hermite_vertices: texture_2d<f32>;
// Per element 2 texels: reflectance ρ_e and emitted radiosity E_e as solved.
@group(0) @binding(4) var surfaces: texture_2d<f32>;
// Per element 2 texels: 1 / the base and emissive textures' means over its triangle.
@group(0) @binding(5) var inverse_means: texture_2d<f32>;
// Hermite: per element 3 texels: its corners' display vertices, the edge from its first
// corner to its second and the edge from its second to its third.
@group(0) @binding(6) var hermite_elements: texture_2d<f32>;
// The textures of the draw's materials (1×1 white where a material has none).
@group(1) @binding(0) var base_texture: texture_2d<f32>;
@group(1) @binding(1) var base_sampler: sampler;
@group(1) @binding(2) var emissive_texture: texture_2d<f32>;
@group(1) @binding(3) var emissive_sampler: sampler;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) element: u32,
    @location(2) vertex: u32,
    @location(3) object: u32,
    // Barycentric coordinates within the element (an element may be drawn as several
    // triangles where a finer neighbour's vertex lies on its edge).
    @location(4) bary: vec3<f32>,
    // Texture coordinates of the base-colour and emissive textures.
    @location(5) uv: vec2<f32>,
    @location(6) uv_emissive: vec2<f32>,
    // alphaMode MASK: texels with texture alpha below this are cut out (0 otherwise).
    @location(7) cutoff: f32,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) smooth_h: vec3<f32>,
    // Constant over a triangle; interpolated anyway (portable to every backend).
    @location(1) flat_h: vec3<f32>,
    @location(2) bary: vec3<f32>,
    @location(3) selected: f32,
    // The element index (exact in f32 below 2^24), constant over the triangle.
    @location(4) element: f32,
    @location(5) uv: vec2<f32>,
    @location(6) uv_emissive: vec2<f32>,
    @location(7) cutoff: f32,
    // ρ_e, E_e and the inverse texture means, constant over the triangle.
    @location(8) reflectance: vec3<f32>,
    @location(9) emission: vec3<f32>,
    @location(10) inverse_mean_base: vec3<f32>,
    @location(11) inverse_mean_emissive: vec3<f32>,
};

fn fetch(t: texture_2d<f32>, i: u32) -> vec3<f32> {
    return textureLoad(t, vec2<i32>(i32(i % u.width), i32(i / u.width)), 0).rgb;
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var o: VertexOut;
    o.clip = u.view_proj * vec4<f32>(v.position, 1.0);
    o.smooth_h = fetch(vertex_values, v.vertex);
    o.flat_h = fetch(element_values, v.element);
    o.bary = v.bary;
    o.selected = select(0.0, 1.0, v.object == u.selected);
    o.element = f32(v.element);
    o.uv = v.uv;
    o.uv_emissive = v.uv_emissive;
    o.cutoff = v.cutoff;
    o.reflectance = fetch(surfaces, 2u * v.element);
    o.emission = fetch(surfaces, 2u * v.element + 1u);
    o.inverse_mean_base = fetch(inverse_means, 2u * v.element);
    o.inverse_mean_emissive = fetch(inverse_means, 2u * v.element + 1u);
    return o;
}

fn luminance(c: vec3<f32>) -> f32 {
    return dot(c, vec3<f32>(0.2126, 0.7152, 0.0722));
}

fn tonemap(l: vec3<f32>) -> vec3<f32> {
    if u.tonemap == 1u {
        return l / (1.0 + luminance(l));
    }
    if u.tonemap == 2u {
        let a = 2.51;
        let b = 0.03;
        let c = 2.43;
        let d = 0.59;
        let e = 0.14;
        return clamp((l * (a * l + b)) / (l * (c * l + d) + e), vec3<f32>(0.0), vec3<f32>(1.0));
    }
    if u.tonemap == 3u {
        return agx(l);
    }
    return clamp(l, vec3<f32>(0.0), vec3<f32>(1.0));
}

// AgX (Troy Sobotka; the minimal fit of Blender 4's curve): `ToneMap::Agx` in
// src/exposure.rs, with the same constants.
fn agx(l: vec3<f32>) -> vec3<f32> {
    let inset = mat3x3<f32>(
        vec3<f32>(0.842479062, 0.0423282422, 0.0423756549),
        vec3<f32>(0.0784336, 0.878468636, 0.0784336),
        vec3<f32>(0.0792237451, 0.0791661275, 0.879142974),
    );
    let outset = mat3x3<f32>(
        vec3<f32>(1.19687901, -0.0528968518, -0.0529716355),
        vec3<f32>(-0.0980208811, 1.15190313, -0.0980434501),
        vec3<f32>(-0.0990297441, -0.0989611768, 1.15107367),
    );
    let min_ev = -12.4739311;
    let max_ev = 4.02606900;
    var v = inset * max(l, vec3<f32>(0.0));
    v = (clamp(log2(max(v, vec3<f32>(1e-10))), vec3<f32>(min_ev), vec3<f32>(max_ev)) - min_ev) / (max_ev - min_ev);
    let x2 = v * v;
    let x4 = x2 * x2;
    v = 15.5 * x4 * x2 - 40.14 * x4 * v + 31.96 * x4 - 6.868 * x2 * v + 0.4298 * x2 + 0.1191 * v - 0.00232;
    v = outset * v;
    return clamp(pow(max(v, vec3<f32>(0.0)), vec3<f32>(2.2)), vec3<f32>(0.0), vec3<f32>(1.0));
}

// Turbo colour map (Mikhailov 2019), polynomial approximation; sRGB-encoded output.
fn turbo(t: f32) -> vec3<f32> {
    let x = clamp(t, 0.0, 1.0);
    let r = 0.13572138 + x * (4.61539260 + x * (-42.66032258 + x * (132.13108234 + x * (-152.94239396 + x * 59.28637943))));
    let g = 0.09140261 + x * (2.19418839 + x * (4.84296658 + x * (-14.18503333 + x * (4.27729857 + x * 2.82956604))));
    let b = 0.10667330 + x * (12.64194608 + x * (-60.58204836 + x * (110.36276771 + x * (-89.90310912 + x * 27.34824973))));
    return clamp(vec3<f32>(r, g, b), vec3<f32>(0.0), vec3<f32>(1.0));
}

fn texel(t: texture_2d<f32>, i: u32) -> vec4<f32> {
    return textureLoad(t, vec2<i32>(i32(i % u.width), i32(i / u.width)), 0);
}

// A display vertex's Hermite data: its value and the gradients of the red, green and blue
// channels.
struct Slopes {
    value: vec3<f32>,
    // Columns: the gradient of each channel, so that `d * g` is the slope along d.
    g: mat3x3<f32>,
};

fn slopes(v: u32) -> Slopes {
    let a = texel(hermite_vertices, 3u * v);
    let b = texel(hermite_vertices, 3u * v + 1u);
    let c = texel(hermite_vertices, 3u * v + 2u);
    var s: Slopes;
    s.value = a.xyz;
    s.g = mat3x3<f32>(vec3<f32>(a.w, b.x, b.y), vec3<f32>(b.z, b.w, c.x), vec3<f32>(c.y, c.z, c.w));
    return s;
}

// -e·edge / |edge|²: the share of `edge` in the direction e towards the centroid.
fn gamma(e: vec3<f32>, edge: vec3<f32>) -> f32 {
    return -dot(e, edge) / max(dot(edge, edge), 1.17549435e-38);
}

// Clough–Tocher element (`DisplayMesh::bezier` in src/mesh/display.rs, step by step): its
// 19 control points from the corners' values and slopes, evaluated in the sub-triangle
// opposite the corner with the smallest barycentric.
fn hermite(e: u32, bary: vec3<f32>) -> vec3<f32> {
    let corners = texel(hermite_elements, 3u * e);
    let e12 = texel(hermite_elements, 3u * e + 1u).xyz;
    let e23 = texel(hermite_elements, 3u * e + 2u).xyz;
    let e31 = -(e12 + e23);
    let v1 = slopes(u32(round(corners.x)));
    let v2 = slopes(u32(round(corners.y)));
    let v3 = slopes(u32(round(corners.z)));
    // Edges: the Hermite cubic of the end values and slopes.
    let c3000 = v1.value;
    let c0300 = v2.value;
    let c0030 = v3.value;
    let c2100 = v1.value + (e12 * v1.g) / 3.0;
    let c2010 = v1.value - (e31 * v1.g) / 3.0;
    let c1200 = v2.value - (e12 * v2.g) / 3.0;
    let c0210 = v2.value + (e23 * v2.g) / 3.0;
    let c1020 = v3.value + (e31 * v3.g) / 3.0;
    let c0120 = v3.value - (e23 * v3.g) / 3.0;
    // Next to each corner towards the centroid: the corner's tangent plane.
    let c2001 = (c2100 + c2010 + c3000) / 3.0;
    let c0201 = (c1200 + c0300 + c0210) / 3.0;
    let c0021 = (c1020 + c0120 + c0030) / 3.0;
    // Cross-edge slopes linear along each edge.
    let e14 = (e12 - e31) / 3.0;
    let e24 = (e23 - e12) / 3.0;
    let e34 = (e31 - e23) / 3.0;
    let q1 = gamma(e24, e23);
    let q2 = gamma(e34, e31);
    let q3 = gamma(e14, e12);
    let c0111_free = (((c0210 - c0120) * 3.0 - c0300 + c0030) * q1
        + (c0210 * 2.0 - c0300 - c0120 + c0021 + c0201)) * 0.5;
    let c1011_free = (((c1020 - c2010) * 3.0 - c0030 + c3000) * q2
        + (c1020 * 2.0 - c0030 - c2010 + c2001 + c0021)) * 0.5;
    let c1101_free = (((c2100 - c1200) * 3.0 - c3000 + c0300) * q3
        + (c2100 * 2.0 - c3000 - c1200 + c2001 + c0201)) * 0.5;
    // No new extremum inside: those three within the edges' control points.
    let lo = min(min(min(c3000, c0300), min(c0030, c2100)),
        min(min(c2010, c1200), min(min(c0210, c1020), c0120)));
    let hi = max(max(max(c3000, c0300), max(c0030, c2100)),
        max(max(c2010, c1200), max(max(c0210, c1020), c0120)));
    let c0111 = clamp(c0111_free, lo, hi);
    let c1011 = clamp(c1011_free, lo, hi);
    let c1101 = clamp(c1101_free, lo, hi);
    // Inner points: C¹ between the three sub-triangles.
    let c1002 = (c1101 + c1011 + c2001) / 3.0;
    let c0102 = (c1101 + c0111 + c0201) / 3.0;
    let c0012 = (c1011 + c0111 + c0021) / 3.0;
    let c0003 = (c1002 + c0102 + c0012) / 3.0;
    let m = min(bary.x, min(bary.y, bary.z));
    let b1 = bary.x - m;
    let b2 = bary.y - m;
    let b3 = bary.z - m;
    let b4 = 3.0 * m;
    return c3000 * (b1 * b1 * b1) + c0300 * (b2 * b2 * b2) + c0030 * (b3 * b3 * b3)
        + c2100 * (3.0 * b1 * b1 * b2) + c2010 * (3.0 * b1 * b1 * b3)
        + c1200 * (3.0 * b1 * b2 * b2) + c0210 * (3.0 * b2 * b2 * b3)
        + c1020 * (3.0 * b1 * b3 * b3) + c0120 * (3.0 * b2 * b3 * b3)
        + c2001 * (3.0 * b1 * b1 * b4) + c0201 * (3.0 * b2 * b2 * b4)
        + c0021 * (3.0 * b3 * b3 * b4)
        + c1101 * (6.0 * b1 * b2 * b4) + c1011 * (6.0 * b1 * b3 * b4)
        + c0111 * (6.0 * b2 * b3 * b4)
        + c1002 * (3.0 * b1 * b4 * b4) + c0102 * (3.0 * b2 * b4 * b4)
        + c0012 * (3.0 * b3 * b4 * b4) + c0003 * (b4 * b4 * b4);
}

@fragment
fn fs_main(i: VertexOut) -> @location(0) vec4<f32> {
    // Sampled first, in uniform control flow (implicit derivatives).
    let base = textureSample(base_texture, base_sampler, i.uv);
    let glow = textureSample(emissive_texture, emissive_sampler, i.uv_emissive).rgb;
    var h = i.flat_h;
    if u.recon == 1u {
        h = i.smooth_h;
    } else if u.recon == 2u {
        h = hermite(u32(round(i.element)), i.bary);
    }
    h = max(h, vec3<f32>(0.0));
    var b = i.reflectance * h + i.emission;
    if u.textures == 1u && u.false_colour == 0u {
        if base.a < i.cutoff {
            discard;
        }
        b = i.reflectance * i.inverse_mean_base * base.rgb * h
            + i.emission * i.inverse_mean_emissive * glow;
    }
    var c: vec3<f32>;
    if u.false_colour == 1u {
        let lum = max(luminance(b), 1e-30);
        let t = (log2(lum) * 0.30103 - u.log_lo) / max(u.log_hi - u.log_lo, 1e-6);
        // The target is sRGB: decode the map's sRGB colours to linear.
        c = pow(turbo(t), vec3<f32>(2.2));
        if lum <= 1e-30 {
            c = vec3<f32>(0.0);
        }
    } else {
        c = tonemap(max(b, vec3<f32>(0.0)) * u.exposure);
    }
    if i.selected > 0.5 {
        c = mix(c, vec3<f32>(1.0, 0.45, 0.05), 0.3);
    }
    if u.wire == 1u {
        let d = fwidth(i.bary);
        let a = smoothstep(vec3<f32>(0.0), d * 1.5, i.bary);
        let edge = 1.0 - min(min(a.x, a.y), a.z);
        let line = select(vec3<f32>(0.8, 0.8, 0.8), vec3<f32>(0.0, 0.0, 0.0), luminance(c) > 0.35);
        c = mix(c, line, edge * 0.9);
    }
    return vec4<f32>(c, 1.0);
}

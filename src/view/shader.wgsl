// The 3D view: one vertex per element corner; radiosity comes from two textures (per
// element for flat reconstruction, per display vertex for Gouraud) so a new snapshot is a
// texture upload, never a vertex-buffer rebuild.

struct Uniforms {
    view_proj: mat4x4<f32>,
    // Multiplier from radiosity B (W/m²) to displayed radiance: 2^EV / π.
    exposure: f32,
    // 0 flat, 1 Gouraud, 2 Hermite (cubic Bézier triangles).
    recon: u32,
    // 0 clamp, 1 Reinhard, 2 ACES (Narkowicz fit).
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
    pad0: f32,
    pad1: f32,
    pad2: f32,
};

@group(0) @binding(0) var<uniform> u: Uniforms;
@group(0) @binding(1) var element_values: texture_2d<f32>;
@group(0) @binding(2) var vertex_values: texture_2d<f32>;
// Hermite: per element 10 control points (RGB), packed as 30 floats in 8 RGBA texels.
@group(0) @binding(3) var bezier_points: texture_2d<f32>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) element: u32,
    @location(2) vertex: u32,
    @location(3) object: u32,
    // Barycentric coordinates within the element (an element may be drawn as several
    // triangles where a finer neighbour's vertex lies on its edge).
    @location(4) bary: vec3<f32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) smooth_b: vec3<f32>,
    // Constant over a triangle; interpolated anyway (portable to every backend).
    @location(1) flat_b: vec3<f32>,
    @location(2) bary: vec3<f32>,
    @location(3) selected: f32,
    // The element index (exact in f32 below 2^24), constant over the triangle.
    @location(4) element: f32,
};

fn fetch(t: texture_2d<f32>, i: u32) -> vec3<f32> {
    return textureLoad(t, vec2<i32>(i32(i % u.width), i32(i / u.width)), 0).rgb;
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var o: VertexOut;
    o.clip = u.view_proj * vec4<f32>(v.position, 1.0);
    o.smooth_b = fetch(vertex_values, v.vertex);
    o.flat_b = fetch(element_values, v.element);
    o.bary = v.bary;
    o.selected = select(0.0, 1.0, v.object == u.selected);
    o.element = f32(v.element);
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
    return clamp(l, vec3<f32>(0.0), vec3<f32>(1.0));
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

// Clough–Tocher element (see `Bezier` in src/mesh/display.rs): 19 control points in 15
// texels, evaluated in the sub-triangle opposite the corner with the smallest barycentric.
fn hermite(e: u32, bary: vec3<f32>) -> vec3<f32> {
    var f: array<f32, 60>;
    for (var k = 0u; k < 15u; k++) {
        let t = texel(bezier_points, e * 15u + k);
        f[4u * k] = t.x;
        f[4u * k + 1u] = t.y;
        f[4u * k + 2u] = t.z;
        f[4u * k + 3u] = t.w;
    }
    let m = min(bary.x, min(bary.y, bary.z));
    let b1 = bary.x - m;
    let b2 = bary.y - m;
    let b3 = bary.z - m;
    let b4 = 3.0 * m;
    let w = array<f32, 19>(
        b1 * b1 * b1, b2 * b2 * b2, b3 * b3 * b3,
        3.0 * b1 * b1 * b2, 3.0 * b1 * b1 * b3, 3.0 * b1 * b2 * b2,
        3.0 * b2 * b2 * b3, 3.0 * b1 * b3 * b3, 3.0 * b2 * b3 * b3,
        3.0 * b1 * b1 * b4, 3.0 * b2 * b2 * b4, 3.0 * b3 * b3 * b4,
        6.0 * b1 * b2 * b4, 6.0 * b1 * b3 * b4, 6.0 * b2 * b3 * b4,
        3.0 * b1 * b4 * b4, 3.0 * b2 * b4 * b4, 3.0 * b3 * b4 * b4,
        b4 * b4 * b4,
    );
    var b = vec3<f32>(0.0);
    for (var k = 0u; k < 19u; k++) {
        b += w[k] * vec3<f32>(f[3u * k], f[3u * k + 1u], f[3u * k + 2u]);
    }
    return b;
}

@fragment
fn fs_main(i: VertexOut) -> @location(0) vec4<f32> {
    var b = i.flat_b;
    if u.recon == 1u {
        b = i.smooth_b;
    } else if u.recon == 2u {
        b = hermite(u32(round(i.element)), i.bary);
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

//! The wgpu renderer of the 3D view, shared by the viewer window, `radiosity render` and the
//! screenshot path: it draws a [`Mesh`] with per-element radiosity into an offscreen colour
//! target (sRGB) with a depth buffer. The viewer shows that target as an egui image; the
//! command line reads it back to a PNG.
//!
//! Vertex data (one vertex per element corner, with its texture coordinates) is uploaded
//! once per mesh, sorted into one draw per combination of textures; a snapshot only
//! writes two `Rgba32Float` textures (the irradiance H per element and per display
//! vertex), which the vertex shader reads with `textureLoad`, so streaming the solution
//! costs 16 bytes per element and vertex, not a vertex-buffer rebuild. Hermite display
//! adds 48 bytes per display vertex (its value and slopes), from which the fragment
//! shader builds each element's Clough–Tocher control points (with the element's corners
//! and edges, 48 bytes per element written with the mesh). The reflectance and
//! emission per element (which edits change) are a third such texture. The shader shows
//! B = ρ(uv)·H + E(uv) (`shader.wgsl`).

use super::camera::Camera;
use super::textures::GpuTextures;
use crate::mesh::{Hermite, Mesh, Reconstruction};
use crate::scene::{Material, Slot, TextureRef};
use anyhow::{Context, Result, anyhow};
use bytemuck::{Pod, Zeroable};
use eframe::egui_wgpu::wgpu;
use glam::Vec3;

/// Width of the value textures (within the 2048 every adapter supports).
const VALUE_WIDTH: u32 = 2048;
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

pub use crate::exposure::ToneMap;

/// The linear colour the 3D view is cleared to (behind the scene).
pub const CLEAR_COLOUR: Vec3 = Vec3::new(0.02, 0.02, 0.025);

/// How the radiosity is shown.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Display {
    pub reconstruction: Reconstruction,
    /// Exposure in stops: displayed radiance is 2^EV · B / π.
    pub ev: f32,
    pub tonemap: ToneMap,
    /// False colour of log10 luminance of B over `log_range` (decades, W/m²).
    pub false_colour: bool,
    pub log_range: (f32, f32),
    pub wireframe: bool,
    pub selected: Option<u32>,
    /// Show the base-colour and emissive textures under the light (off: each element in
    /// the mean colour the solver used, the solution alone).
    pub textures: bool,
}

impl Default for Display {
    fn default() -> Self {
        Display {
            reconstruction: Reconstruction::Hermite,
            ev: 0.0,
            tonemap: ToneMap::default(),
            false_colour: false,
            log_range: (-2.0, 2.0),
            wireframe: false,
            selected: None,
            textures: true,
        }
    }
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Uniforms {
    view_proj: [[f32; 4]; 4],
    exposure: f32,
    recon: u32,
    tonemap: u32,
    false_colour: u32,
    wire: u32,
    selected: u32,
    width: u32,
    log_lo: f32,
    log_hi: f32,
    textures: u32,
    pad: [f32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Vertex {
    position: [f32; 3],
    element: u32,
    vertex: u32,
    object: u32,
    /// Barycentric coordinates within the element (for the wireframe and Hermite).
    bary: [f32; 3],
    /// Texture coordinates, base colour and emissive.
    uv: [f32; 2],
    uv_emissive: [f32; 2],
    /// Texture alpha below which the fragment is cut out (`alphaMode: MASK`), else 0.
    cutoff: f32,
}

/// Pipeline and uniforms: one per device.
pub struct Renderer {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    texture_layout: wgpu::BindGroupLayout,
    uniforms: wgpu::Buffer,
}

/// The textures one draw samples: a material's base-colour and emissive textures.
type TextureKey = (Option<TextureRef>, Option<TextureRef>);

/// A mesh on the GPU with its value textures.
pub struct GpuMesh {
    vertices: wgpu::Buffer,
    /// Vertex ranges drawn with one texture bind group each.
    draws: Vec<(std::ops::Range<u32>, wgpu::BindGroup)>,
    element_values: wgpu::Texture,
    vertex_values: wgpu::Texture,
    /// Hermite display: per display vertex the value and slopes ([`HERMITE_TEXELS`]), and
    /// per element its corners' vertices and two edges, which the shader builds its
    /// Clough–Tocher control points from (`None` when the device cannot hold them).
    hermite: Option<HermiteTextures>,
    surfaces: wgpu::Texture,
    bind_group: wgpu::BindGroup,
    /// The mesh it was made from (to check snapshot sizes).
    pub elements: usize,
    pub display_vertices: usize,
}

/// The textures of Hermite display.
struct HermiteTextures {
    vertices: wgpu::Texture,
    elements: wgpu::Texture,
}

/// RGBA texels per display vertex for Hermite display: its value and the gradient of each
/// channel (12 floats).
const HERMITE_TEXELS: usize = 3;

/// RGBA texels per element for Hermite display: its corners' display vertices (exact in
/// f32 below 2²⁴) and the edges from its first corner to its second and from its second
/// to its third, in the mesh frame.
const CORNER_TEXELS: usize = 3;

/// An offscreen colour + depth target.
pub struct Target {
    pub color: wgpu::Texture,
    pub view: wgpu::TextureView,
    /// The same texels viewed as plain `Rgba8Unorm`, for egui: it takes a native
    /// texture's values as sRGB-encoded ("Texture must have the texture format
    /// Rgba8Unorm", `egui_wgpu::Renderer::register_native_texture`), and sampling the sRGB
    /// view would hand it linear values, shown too dark.
    pub encoded_view: wgpu::TextureView,
    depth: wgpu::TextureView,
    pub size: [u32; 2],
}

impl Target {
    pub fn new(device: &wgpu::Device, size: [u32; 2]) -> Target {
        let size = [size[0].max(1), size[1].max(1)];
        let extent = wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        };
        let color = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("radiosity view colour"),
            size: extent,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: COLOR_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[wgpu::TextureFormat::Rgba8Unorm],
        });
        let depth = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("radiosity view depth"),
            size: extent,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        Target {
            view: color.create_view(&Default::default()),
            encoded_view: color.create_view(&wgpu::TextureViewDescriptor {
                format: Some(wgpu::TextureFormat::Rgba8Unorm),
                ..Default::default()
            }),
            depth: depth.create_view(&Default::default()),
            color,
            size,
        }
    }
}

fn value_texture(device: &wgpu::Device, n: usize, label: &str) -> wgpu::Texture {
    let rows = (n as u32).div_ceil(VALUE_WIDTH).max(1);
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: VALUE_WIDTH,
            height: rows,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}

fn write_values(queue: &wgpu::Queue, texture: &wgpu::Texture, values: &[Vec3]) {
    write_texels(
        queue,
        texture,
        values.iter().map(|v| [v.x, v.y, v.z, 1.0]).collect(),
    );
}

/// Writes `data` (one RGBA texel each, in index order) into the first rows of `texture`,
/// padding the last row.
fn write_texels(queue: &wgpu::Queue, texture: &wgpu::Texture, mut data: Vec<[f32; 4]>) {
    if data.is_empty() {
        return;
    }
    let rows = (data.len() as u32).div_ceil(VALUE_WIDTH);
    data.resize((rows * VALUE_WIDTH) as usize, [0.0; 4]);
    queue.write_texture(
        texture.as_image_copy(),
        bytemuck::cast_slice(&data),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(VALUE_WIDTH * 16),
            rows_per_image: None,
        },
        wgpu::Extent3d {
            width: VALUE_WIDTH,
            height: rows,
            depth_or_array_layers: 1,
        },
    );
}

impl Renderer {
    pub fn new(device: &wgpu::Device) -> Renderer {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("radiosity view shader"),
            source: wgpu::ShaderSource::Wgsl(include_str!("shader.wgsl").into()),
        });
        let texture_entry = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("radiosity view bind group layout"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                texture_entry(1),
                texture_entry(2),
                wgpu::BindGroupLayoutEntry {
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ..texture_entry(3)
                },
                texture_entry(4),
                texture_entry(5),
                wgpu::BindGroupLayoutEntry {
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ..texture_entry(6)
                },
            ],
        });
        let image_entry = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: true },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let sampler_entry = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
            count: None,
        };
        let texture_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("radiosity material textures layout"),
            entries: &[
                image_entry(0),
                sampler_entry(1),
                image_entry(2),
                sampler_entry(3),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("radiosity view pipeline layout"),
            bind_group_layouts: &[Some(&layout), Some(&texture_layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("radiosity view pipeline"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<Vertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Uint32, 2 => Uint32, 3 => Uint32, 4 => Float32x3, 5 => Float32x2, 6 => Float32x2, 7 => Float32],
                })],
                compilation_options: Default::default(),
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                // Each side of a surface is its own element (double-sided materials have a
                // back patch wound the other way), so back faces are culled: no z-fighting,
                // and single-sided walls are see-through from outside.
                cull_mode: Some(wgpu::Face::Back),
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                targets: &[Some(wgpu::ColorTargetState {
                    format: COLOR_FORMAT,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
                compilation_options: Default::default(),
            }),
            multiview_mask: None,
            cache: None,
        });
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("radiosity view uniforms"),
            size: std::mem::size_of::<Uniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Renderer {
            pipeline,
            layout,
            texture_layout,
            uniforms,
        }
    }

    /// Uploads `mesh`'s elements (one vertex per corner, drawn with the textures of
    /// `materials` from `textures`) and makes its value textures.
    pub fn upload(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        mesh: &Mesh,
        materials: &[Material],
        textures: &GpuTextures,
    ) -> GpuMesh {
        use wgpu::util::DeviceExt;
        let (vertices, groups) = triangles(mesh, materials);
        let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("radiosity view vertices"),
            contents: if vertices.is_empty() {
                &[0u8; 24]
            } else {
                bytemuck::cast_slice(&vertices)
            },
            usage: wgpu::BufferUsages::VERTEX,
        });
        let element_values = value_texture(device, mesh.elements.len(), "element radiosity");
        let vertex_values = value_texture(
            device,
            mesh.display.positions.len(),
            "display-vertex radiosity",
        );
        // Hermite data, when the device can hold it and the vertex indices are exact.
        let fits = |texels: usize| {
            (texels as u64).div_ceil(VALUE_WIDTH as u64)
                <= device.limits().max_texture_dimension_2d as u64
        };
        let vertices = mesh.display.positions.len();
        let hermite = (fits(vertices * HERMITE_TEXELS)
            && fits(mesh.elements.len() * CORNER_TEXELS)
            && vertices < 1 << 24)
            .then(|| {
                let elements = value_texture(
                    device,
                    mesh.elements.len() * CORNER_TEXELS,
                    "Hermite element corners",
                );
                write_texels(queue, &elements, hermite_corners(mesh));
                HermiteTextures {
                    vertices: value_texture(device, vertices * HERMITE_TEXELS, "Hermite slopes"),
                    elements,
                }
            });
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let (hermite_vertices, hermite_elements) = match &hermite {
            Some(h) => (view(&h.vertices), view(&h.elements)),
            None => (view(&element_values), view(&element_values)),
        };
        let surfaces = value_texture(device, 2 * mesh.elements.len(), "element surfaces");
        let inverse_means = value_texture(device, 2 * mesh.elements.len(), "texture means");
        write_values(queue, &inverse_means, &inverse_texture_means(mesh));
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("radiosity view bind group"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.uniforms.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(
                        &element_values.create_view(&Default::default()),
                    ),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(
                        &vertex_values.create_view(&Default::default()),
                    ),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(&hermite_vertices),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: wgpu::BindingResource::TextureView(
                        &surfaces.create_view(&Default::default()),
                    ),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: wgpu::BindingResource::TextureView(
                        &inverse_means.create_view(&Default::default()),
                    ),
                },
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: wgpu::BindingResource::TextureView(&hermite_elements),
                },
            ],
        });
        let draws = groups
            .into_iter()
            .map(|((base, emissive), range)| {
                let (base_view, base_sampler) = textures.binding(base);
                let (glow_view, glow_sampler) = textures.binding(emissive);
                let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("radiosity material textures"),
                    layout: &self.texture_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: wgpu::BindingResource::TextureView(base_view),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: wgpu::BindingResource::Sampler(base_sampler),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: wgpu::BindingResource::TextureView(glow_view),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: wgpu::BindingResource::Sampler(glow_sampler),
                        },
                    ],
                });
                (range, group)
            })
            .collect();
        GpuMesh {
            vertices: buffer,
            draws,
            element_values,
            vertex_values,
            hermite,
            surfaces,
            bind_group,
            elements: mesh.elements.len(),
            display_vertices: mesh.display.positions.len(),
        }
    }

    /// Draws `mesh` (or clears, with none) into `target` as seen by `camera`.
    pub fn render(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &Target,
        mesh: Option<&GpuMesh>,
        camera: &Camera,
        display: &Display,
    ) {
        let aspect = target.size[0] as f32 / target.size[1] as f32;
        let u = Uniforms {
            view_proj: camera.view_proj(aspect).to_cols_array_2d(),
            exposure: 2f32.powf(display.ev) / std::f32::consts::PI,
            recon: match display.reconstruction {
                Reconstruction::Flat => 0,
                Reconstruction::Gouraud => 1,
                Reconstruction::Hermite => 2,
            },
            tonemap: match display.tonemap {
                ToneMap::Clamp => 0,
                ToneMap::Reinhard => 1,
                ToneMap::Aces => 2,
                ToneMap::Agx => 3,
            },
            false_colour: display.false_colour as u32,
            wire: display.wireframe as u32,
            selected: display.selected.unwrap_or(u32::MAX),
            width: VALUE_WIDTH,
            log_lo: display.log_range.0,
            log_hi: display.log_range.1,
            textures: display.textures as u32,
            pad: [0.0; 2],
        };
        queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&u));
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("radiosity view pass"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target.view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: CLEAR_COLOUR.x as f64,
                            g: CLEAR_COLOUR.y as f64,
                            b: CLEAR_COLOUR.z as f64,
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &target.depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            if let Some(mesh) = mesh
                && !mesh.draws.is_empty()
            {
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &mesh.bind_group, &[]);
                pass.set_vertex_buffer(0, mesh.vertices.slice(..));
                for (range, textures) in &mesh.draws {
                    pass.set_bind_group(1, textures, &[]);
                    pass.draw(range.clone(), 0..1);
                }
            }
        }
        queue.submit([encoder.finish()]);
    }
}

impl GpuMesh {
    /// Writes a snapshot: the irradiance H per element and at the display vertices (sizes
    /// must match the mesh; a mismatched snapshot, from another mesh, is ignored).
    pub fn set_values(&self, queue: &wgpu::Queue, elements: &[Vec3], vertices: &[Vec3]) -> bool {
        if elements.len() != self.elements || vertices.len() != self.display_vertices {
            return false;
        }
        write_values(queue, &self.element_values, elements);
        write_values(queue, &self.vertex_values, vertices);
        true
    }

    /// Writes the reflectance ρ and emitted radiosity E per element the solution was
    /// solved with (ignored when the sizes do not match the mesh).
    pub fn set_surfaces(
        &self,
        queue: &wgpu::Queue,
        reflectance: &[Vec3],
        emission: &[Vec3],
    ) -> bool {
        if reflectance.len() != self.elements || emission.len() != self.elements {
            return false;
        }
        let texels: Vec<Vec3> = reflectance
            .iter()
            .zip(emission)
            .flat_map(|(r, e)| [*r, *e])
            .collect();
        write_values(queue, &self.surfaces, &texels);
        true
    }

    /// Whether this mesh can show Hermite reconstruction (its data fit the textures).
    pub fn supports_hermite(&self) -> bool {
        self.hermite.is_some()
    }

    /// Writes the Hermite values and slopes at the display vertices (see [`Hermite`];
    /// ignored when the sizes do not match the mesh).
    pub fn set_hermite(&self, queue: &wgpu::Queue, h: &Hermite) -> bool {
        let Some(t) = &self.hermite else { return false };
        if h.values.len() != self.display_vertices || h.gradients.len() != self.display_vertices {
            return false;
        }
        let texels = h
            .values
            .iter()
            .zip(&h.gradients)
            .flat_map(|(v, [r, g, b])| {
                [
                    [v.x, v.y, v.z, r.x],
                    [r.y, r.z, g.x, g.y],
                    [g.z, b.x, b.y, b.z],
                ]
            })
            .collect();
        write_texels(queue, &t.vertices, texels);
        true
    }
}

/// Per element, what the shader's Clough–Tocher element needs besides the vertex data
/// ([`CORNER_TEXELS`]).
fn hermite_corners(mesh: &Mesh) -> Vec<[f32; 4]> {
    mesh.elements
        .iter()
        .flat_map(|e| {
            let [a, b, c] = e.corners.map(|v| v as f32);
            let [p1, p2, p3] = e.verts;
            let (e12, e23) = (p2 - p1, p3 - p2);
            [
                [a, b, c, 0.0],
                [e12.x, e12.y, e12.z, 0.0],
                [e23.x, e23.y, e23.z, 0.0],
            ]
        })
        .collect()
}

/// Why `adapter` cannot draw the view, if it cannot. The colour target is viewed both as
/// sRGB and as plain RGBA8 ([`Target`]), which takes texture view formats, a capability
/// that OpenGL adapters lack (a machine without a Vulkan driver gets one): creating the
/// target there panics inside wgpu.
pub fn unsupported(adapter: &wgpu::Adapter) -> Option<String> {
    let flags = adapter.get_downlevel_capabilities().flags;
    if flags.contains(wgpu::DownlevelFlags::VIEW_FORMATS) {
        return None;
    }
    Some(format!(
        "the graphics adapter {} cannot draw the view: it lacks texture view formats \
         (install Mesa's mesa-vulkan-drivers for a software Vulkan one)",
        adapter_name(adapter)
    ))
}

/// The adapter's name and backend, as messages and statistics show it.
pub fn adapter_name(adapter: &wgpu::Adapter) -> String {
    let info = adapter.get_info();
    format!("{} ({:?})", info.name, info.backend)
}

/// A device with no window, its queue and its adapter's name ([`adapter_name`]).
pub struct Headless {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub adapter: String,
}

/// A device with no window (for `render`, screenshots in tests): the same software or
/// hardware adapter choice as the viewer, preferring Vulkan.
pub fn headless_device() -> Result<Headless> {
    use eframe::egui_wgpu;
    let setup =
        egui_wgpu::WgpuSetup::CreateNew(egui_wgpu::WgpuSetupCreateNew::without_display_handle());
    let instance = pollster::block_on(setup.new_instance());
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        ..Default::default()
    }))
    .map_err(|e| {
        anyhow!("no graphics adapter (install Mesa's mesa-vulkan-drivers for a software one): {e}")
    })?;
    if let Some(why) = unsupported(&adapter) {
        return Err(anyhow!(why));
    }
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("radiosity headless"),
        required_limits: wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits()),
        ..Default::default()
    }))
    .context("creating the graphics device")?;
    Ok(Headless {
        device,
        queue,
        adapter: adapter_name(&adapter),
    })
}

/// Reads `target` back as an RGBA8 image (sRGB bytes, as shown on screen).
pub fn read_back(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    target: &Target,
) -> Result<image::RgbaImage> {
    let [w, h] = target.size;
    let unpadded = w * 4;
    let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let padded = unpadded.div_ceil(align) * align;
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("radiosity readback"),
        size: (padded * h) as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_texture_to_buffer(
        target.color.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: None,
            },
        },
        wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
    );
    let index = queue.submit([encoder.finish()]);
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::Wait {
            submission_index: Some(index),
            timeout: Some(std::time::Duration::from_secs(60)),
        })
        .map_err(|e| anyhow!("waiting for the GPU: {e}"))?;
    rx.recv()
        .context("GPU readback dropped")?
        .map_err(|e| anyhow!("mapping the readback buffer: {e}"))?;
    let data = slice
        .get_mapped_range()
        .map_err(|e| anyhow!("reading the readback buffer: {e:?}"))?;
    let mut pixels = Vec::with_capacity((unpadded * h) as usize);
    for row in data.chunks_exact(padded as usize) {
        pixels.extend_from_slice(&row[..unpadded as usize]);
    }
    drop(data);
    buffer.unmap();
    image::RgbaImage::from_raw(w, h, pixels).context("readback size mismatch")
}

/// A solution as the renderer draws it, per element: the radiosity B (for the exposure)
/// and the reflectance ρ and emitted radiosity E it was solved with.
pub struct Solution<'a> {
    pub radiosity: &'a [Vec3],
    pub reflectance: &'a [Vec3],
    pub emission: &'a [Vec3],
}

/// Renders `solution` on `mesh` to an image, offscreen on `headless`, with the textures of
/// `materials` (indices into `images`).
#[allow(clippy::too_many_arguments)]
pub fn render_image(
    headless: &Headless,
    mesh: &Mesh,
    solution: &Solution,
    materials: &[Material],
    images: &[std::sync::Arc<crate::scene::Image>],
    camera: &Camera,
    display: &Display,
    size: [u32; 2],
) -> Result<image::RgbaImage> {
    let Headless { device, queue, .. } = headless;
    let renderer = Renderer::new(device);
    let textures = GpuTextures::new(device, queue, images);
    let gpu = renderer.upload(device, queue, mesh, materials, &textures);
    let irradiance =
        crate::solver::irradiance(solution.radiosity, solution.reflectance, solution.emission);
    let vertex = if display.reconstruction == Reconstruction::Hermite {
        let (vertex, hermite) = mesh.display.smooth_values(&mesh.elements, &irradiance);
        if !gpu.set_hermite(queue, &hermite) {
            return Err(anyhow!(
                "too many elements for Hermite display on this device (use --mode gouraud)"
            ));
        }
        vertex
    } else {
        mesh.display.vertex_values(&mesh.elements, &irradiance)
    };
    gpu.set_values(queue, &irradiance, &vertex);
    gpu.set_surfaces(queue, solution.reflectance, solution.emission);
    let target = Target::new(device, size);
    renderer.render(device, queue, &target, Some(&gpu), camera, display);
    read_back(device, queue, &target)
}

/// Per element, its patch's [`crate::mesh::PatchTexture::inverse_means`] (1 where untextured).
fn inverse_texture_means(mesh: &Mesh) -> Vec<Vec3> {
    mesh.elements
        .iter()
        .flat_map(|e| {
            mesh.textures
                .get(e.patch as usize)
                .map_or([Vec3::ONE; 2], |t| t.inverse_means())
        })
        .collect()
}

/// The element triangles to draw (conforming at T-vertices, `Mesh::conforming_triangles`),
/// each corner with its texture coordinates, grouped by the textures of their material
/// (`materials`), with each group's range: one draw per group.
fn triangles(
    mesh: &Mesh,
    materials: &[Material],
) -> (Vec<Vertex>, Vec<(TextureKey, std::ops::Range<u32>)>) {
    let t_vertices = mesh.t_vertices();
    let mut groups: Vec<(TextureKey, Vec<Vertex>)> = Vec::new();
    for (i, e) in mesh.elements.iter().enumerate() {
        let patch = &mesh.patches[e.patch as usize];
        let m = materials.get(patch.material as usize);
        let key = m.map_or((None, None), |m| (m.base_texture, m.emissive_texture));
        let group = match groups.iter().position(|(k, _)| *k == key) {
            Some(g) => g,
            None => {
                groups.push((key, Vec::new()));
                groups.len() - 1
            }
        };
        let cutoff = m.and_then(|m| m.alpha_cutoff).unwrap_or(0.0);
        let uv = |p: Vec3, slot: Slot| {
            mesh.texture_uv(i as u32, p, slot)
                .map_or([0.0; 2], |uv| uv.to_array())
        };
        let out = &mut groups[group].1;
        mesh.conforming_triangles(i as u32, &t_vertices, |corners| {
            for c in corners {
                out.push(Vertex {
                    position: c.position.to_array(),
                    element: i as u32,
                    vertex: c.vertex,
                    object: patch.object,
                    bary: c.bary,
                    uv: uv(c.position, Slot::Base),
                    uv_emissive: uv(c.position, Slot::Emissive),
                    cutoff,
                });
            }
        });
    }
    let mut out = Vec::with_capacity(groups.iter().map(|(_, v)| v.len()).sum());
    let mut ranges = Vec::with_capacity(groups.len());
    for (key, vertices) in groups {
        let start = out.len() as u32;
        out.extend(vertices);
        ranges.push((key, start..out.len() as u32));
    }
    (out, ranges)
}

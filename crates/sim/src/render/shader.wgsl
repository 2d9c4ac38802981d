// One pass writes colour (rgba8) and a uint target: linear depth bits,
// segment id and the packed world normal (GL cannot render R32Float).
// Glass (alpha below 1 in the vertex colour) is drawn after the opaque
// meshes, by the same shader with blending on the colour target.
const MAX_PARTS: u32 = 66u;

struct Camera {
    clip_from_camera: mat4x4<f32>,
    camera_from_world: mat4x4<f32>,
    eye: vec4<f32>,
    light: vec4<f32>,
};

@group(0) @binding(0) var<uniform> camera: Camera;
@group(0) @binding(1) var<uniform> parts: array<mat4x4<f32>, 66>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) part: u32,
    @location(2) color: u32,
    @location(3) segment: u32,
};

struct VertexOut {
    // Invariant: the glass pass tests depth for equality with the glass
    // depth pass, so both must compute the same position.
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) view_z: f32,
    @location(2) @interpolate(flat) color: u32,
    @location(3) @interpolate(flat) segment: u32,
};

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    let world = parts[min(v.part, MAX_PARTS - 1u)] * vec4<f32>(v.position, 1.0);
    let cam = camera.camera_from_world * world;
    out.clip = camera.clip_from_camera * cam;
    out.world = world.xyz;
    out.view_z = cam.z;
    out.color = v.color;
    out.segment = v.segment;
    return out;
}

struct FragOut {
    @location(0) color: vec4<f32>,
    @location(1) data: vec4<u32>,
};

fn facing_normal(in: VertexOut) -> vec3<f32> {
    let n = normalize(cross(dpdx(in.world), dpdy(in.world)));
    if (dot(n, camera.eye.xyz - in.world) < 0.0) {
        return -n;
    }
    return n;
}

fn shaded(in: VertexOut, n: vec3<f32>) -> vec4<f32> {
    let base = unpack4x8unorm(in.color);
    let k = 0.35 + 0.65 * max(dot(n, camera.light.xyz), 0.0);
    return vec4<f32>(base.rgb * k, base.a);
}

@fragment
fn fs_main(in: VertexOut) -> FragOut {
    let n = facing_normal(in);
    var out: FragOut;
    out.color = shaded(in, n);
    out.data = vec4<u32>(bitcast<u32>(in.view_z), in.segment, pack2x16snorm(n.xy), pack2x16snorm(vec2<f32>(n.z, 0.0)));
    return out;
}

// Glass seen by a depth camera that reads nothing there: its colour, and
// the data of a pixel that sees nothing (depth 0, background, no normal).
@fragment
fn fs_no_reading(in: VertexOut) -> FragOut {
    var out: FragOut;
    out.color = shaded(in, facing_normal(in));
    out.data = vec4<u32>(0u);
    return out;
}

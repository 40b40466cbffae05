// The splat attributes of the compute visibility pass (visibility.comp) and of the opaque resolve
// (opaque_resolve.frag) read from the attribute buffers, which renderer.py binds as shader storage
// (compute_visibility.COMPUTE_BINDINGS), tightly packed float32; OpenGL 4.3. Requires
// splat_attributes.glsl under COMPUTE_SPLATS (the attributes as plain globals).

layout(std430, binding = 0) readonly buffer Positions { float position_data[]; };
layout(std430, binding = 1) readonly buffer Normals { float normal_data[]; };
layout(std430, binding = 2) readonly buffer AxesU { float u_data[]; };
layout(std430, binding = 3) readonly buffer AxesV { float v_data[]; };
#ifdef HAS_CLIP_LINES
layout(std430, binding = 4) readonly buffer Clip0 { float clip0_data[]; };
layout(std430, binding = 5) readonly buffer Clip1 { float clip1_data[]; };
#endif
#ifdef HAS_NORMAL_FIELD
layout(std430, binding = 6) readonly buffer NormalField { float normal_field_data[]; };
#endif
#ifdef SEQUENTIAL_LOD
layout(std430, binding = 7) readonly buffer Lod { float lod_data[]; };
#endif
#ifdef READ_COLOR
layout(std430, binding = 8) readonly buffer Colors { float color_data[]; };
#endif

vec3 read3(int i, int which) {
    int k = 3 * i;
    if (which == 0) return vec3(position_data[k], position_data[k + 1], position_data[k + 2]);
    if (which == 1) return vec3(normal_data[k], normal_data[k + 1], normal_data[k + 2]);
    if (which == 2) return vec3(u_data[k], u_data[k + 1], u_data[k + 2]);
    return vec3(v_data[k], v_data[k + 1], v_data[k + 2]);
}

// The splat attributes the vertex shaders read, from the buffers; (0, 0, 0) where there is no buffer,
// as OpenGL's default vertex attribute reads.
void read_splat(int i) {
    in_corner = vec2(0.0);
#ifdef READ_COLOR
    in_color = vec3(color_data[3 * i], color_data[3 * i + 1], color_data[3 * i + 2]);
#else
    in_color = vec3(0.0);
#endif
    in_position = read3(i, 0);
    in_normal = read3(i, 1);
    in_u = read3(i, 2);
    in_v = read3(i, 3);
#ifdef HAS_CLIP_LINES
    in_clip0 = vec3(clip0_data[3 * i], clip0_data[3 * i + 1], clip0_data[3 * i + 2]);
    in_clip1 = vec3(clip1_data[3 * i], clip1_data[3 * i + 1], clip1_data[3 * i + 2]);
#else
    in_clip0 = vec3(0.0);
    in_clip1 = vec3(0.0);
#endif
#ifdef HAS_NORMAL_FIELD
    in_normal_field = vec2(normal_field_data[2 * i], normal_field_data[2 * i + 1]);
#else
    in_normal_field = vec2(0.0);
#endif
#ifdef SEQUENTIAL_LOD
    in_lod = vec4(lod_data[4 * i], lod_data[4 * i + 1], lod_data[4 * i + 2], lod_data[4 * i + 3]);
#endif
}

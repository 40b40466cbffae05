// Camera uniforms and the projection helpers shared by every splat shader.
// Mirrors surfsplat/reference.py: window pixels with y up, camera looks down -z.
// One std140 block of the frame's buffer, written once per frame and shared by every program
// (rendering/uniform_blocks.py reads the members' layout from this declaration).
layout(std140) uniform Camera {
    mat4 u_view;        // world -> camera
    vec4 u_tile;        // the window rectangle of the full image this draw covers: origin (x, y), size (w, h)
    vec2 u_viewport;    // width, height in pixels
    vec2 u_near_far;    // clip distances along -z, model units
    float u_focal;      // focal length in pixels: (height / 2) / tan(fov / 2)
};

// The full image's window pixel of the fragment (fragment shaders only): tiles offset gl_FragCoord.
#define FRAG_PX (gl_FragCoord.xy + u_tile.xy)

vec2 project_px(vec3 p) {
    return 0.5 * u_viewport + u_focal * p.xy / (-p.z);
}

// Camera-space direction (z = -1) of the viewing ray through a window pixel.
vec3 pixel_ray(vec2 px) {
    return vec3((px - 0.5 * u_viewport) / u_focal, -1.0);
}

// Linear stored depth: every splat shader writes gl_FragDepth itself.
float window_depth(float z) {
    return (z - u_near_far.x) / (u_near_far.y - u_near_far.x);
}

vec4 px_to_clip(vec2 px) {
    return vec4((px - u_tile.xy) / u_tile.zw * 2.0 - 1.0, 0.0, 1.0);
}

// The tile's window box, full-image pixels: quads are clipped to it.
vec2 tile_lo() { return u_tile.xy; }
vec2 tile_hi() { return u_tile.xy + u_tile.zw; }

// Outside every clip volume: the instance draws nothing.
const vec4 CULLED = vec4(2.0, 2.0, 2.0, 1.0);

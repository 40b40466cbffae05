// The frame's rendering options (RenderOptions, Renderer.frame_uniforms) that the splat programs and
// the normalization pass read. One std140 block of the frame's buffer, written once per frame and
// shared by every program, like camera.glsl's (rendering/uniform_blocks.py reads this declaration).
layout(std140) uniform Options {
    float u_depth_epsilon;   // visibility offset along the viewing ray, in splat radii
    float u_supersample;     // sub-pixels per output pixel along x and y (K)
    bool u_cull_backfaces;   // closed, outward-oriented models only
    bool u_separate_sides;   // blend only splats seen from the same side as the nearest one
    bool u_clip_fringe;      // drop filter fringes beyond a splat's disk over nothing or a farther surface
    bool u_deferred;         // lighting after blending: splats carry their albedo
};

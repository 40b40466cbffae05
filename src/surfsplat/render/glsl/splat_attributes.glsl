// Per-instance splat attributes (one instance = one splat) and the quad corner.
in vec2 in_corner;      // (-1,-1) .. (1,1): which corner of the bounding quad
in vec3 in_position;    // model space
in vec3 in_normal;      // unit center (shading) normal; the plane is spanned by u and v
in vec3 in_color;       // linear RGB albedo
in vec3 in_u;           // scaled tangent axis
in vec3 in_v;           // scaled tangent axis, orthogonal to in_u
in vec3 in_clip0;       // clip lines (a, b, c) in normalized (s, t): kept where a s + b t + c >= 0;
in vec3 in_clip1;       // unbound (no clip lines) they read (0, 0, 0): nothing is clipped
in vec2 in_normal_field; // (alpha, beta) of the linear normal field (Botsch 2004, eq. 2); unbound: (0, 0)

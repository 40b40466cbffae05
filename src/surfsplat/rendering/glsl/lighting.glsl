// Two-sided Blinn-Phong with up to MAX_LIGHTS directional lights (surfsplat/lighting.py).
// One std140 block of the frame's buffer, like camera.glsl's (rendering/uniform_blocks.py).
layout(std140) uniform Lighting {
    vec3 u_light_dirs[MAX_LIGHTS];   // camera space, unit, toward the lights
    vec4 u_material;        // ka, kd, ks, shininess
    int u_num_lights;
    bool u_lighting;
};

vec3 shade(vec3 albedo, vec3 n, vec3 view) {
    if (!u_lighting) return albedo;
    if (dot(n, view) < 0.0) n = -n;
    float diffuse = 0.0;
    float specular = 0.0;
    for (int i = 0; i < u_num_lights; ++i) {
        vec3 l = u_light_dirs[i];
        diffuse += max(0.0, dot(n, l));
        vec3 h = normalize(l + view);
        specular += pow(max(0.0, dot(n, h)), u_material.w);
    }
    return albedo * (u_material.x + u_material.y * diffuse) + u_material.z * specular;
}

// Technique "flat": exact ray/disk test per pixel, opaque.
#include "camera.glsl"
#include "splat_fragment.glsl"

flat in vec3 v_color;
flat in vec3 v_normal;

void main() {
    vec3 ray = pixel_ray(FRAG_PX);
    float z;
    if (!ray_disk(ray, z)) discard;
    emit(ray, z, 1.0, v_color, v_normal);
}

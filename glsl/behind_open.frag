#version 460
// behind_open: the G-buffer's clear values (zero ray, frame and curve; depth 0 from the
// vertex stage) over the behind layer's listed tiles (src/passes/behind_open.rs). The
// CURVE variant also writes the curve attachment.
// dispmap-variant: CURVE

layout(location = 0) out vec4 out_ray;
layout(location = 1) out uvec2 out_frame;
#ifdef CURVE
layout(location = 2) out vec2 out_curve;
#endif

void main() {
    out_ray = vec4(0.0);
    out_frame = uvec2(0u);
#ifdef CURVE
    out_curve = vec2(0.0);
#endif
}

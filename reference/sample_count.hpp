// sample_count.hpp — ivr's sample count (docs/integrators.md) on the host: whether a camera ray meets the box and
// into how many segments the fixed-step integrators cut it, from float32 roundings of the inputs
// through correctly rounded float32 operations (kernels/sample_count.cl is the device's copy).
#pragma once
#include <array>
#include <glm/vec3.hpp>

#include "ivr/scene.hpp"

namespace ivr::reference {

// A camera as the device buffer holds it (IVR_CAMERA_STRIDE's first 13 values, float32): eye,
// forward, right and up scaled to the image plane, orthographic flag.
using PackedCamera = std::array<float, 13>;
PackedCamera packed_camera(const ivr::Camera& camera);

// How the count's float32 quotients and roots are formed: correctly rounded (the definition), or
// as a device with a faithful but 1-ulp-high division and sqrt would form them, either corrected
// by fma residuals (the kernel's fallback, IVR_COUNT_RESIDUAL) or used as they are (what a count
// from the device's plain arithmetic would be).
enum class CountArithmetic { correctly_rounded, one_ulp_high_corrected, one_ulp_high };
float count_divide(float a, float b, CountArithmetic arithmetic);
float count_sqrt(float a, CountArithmetic arithmetic);

// 0 where the ray of pixel (x, y) misses the box, else n >= 1.
unsigned sample_count(const PackedCamera& camera, int x, int y, int width, int height,
                      const glm::dvec3& box_min, const glm::dvec3& box_max, double step_world,
                      CountArithmetic arithmetic = CountArithmetic::correctly_rounded);
unsigned sample_count(const ivr::Scene& scene, int view, int x, int y, double step_world);
// The same of a ray-list row (origin, direction, t_start, t_end; kernels/sample_count.cl with
// IVR_RAY_LIST): the float32 roundings of its values, the slabs from [t_start, t_end].
unsigned ray_sample_count(const double* ray, const glm::dvec3& box_min, const glm::dvec3& box_max,
                          double step_world);

}  // namespace ivr::reference

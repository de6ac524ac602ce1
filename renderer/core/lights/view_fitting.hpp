// What the light kinds' view fitting shares with light_math.cpp (defined
// there), and the orthographic fitting the directional light and the sun
// share (defined in directional.cpp). Inside core only.
#pragma once

#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "core/light_math.hpp"
#include "core/request.hpp"
#include "core/scene.hpp"

namespace umbra {

/// Fraction of a map's side kept free for `texels` texels on each side (at
/// most half the side, for tiny maps and wide kernels).
double spare_fraction(int texels, int size);
/// m * (p, 1), without the division by w.
glm::dvec3 transform(const glm::dmat4& m, const glm::dvec3& p);
/// object_bounds of every object, in the scene's order.
std::vector<Aabb> bounds_of(const Scene& scene);
/// Texel size of a view, read from its projection.
void set_texel_size(ShadowView& v, bool perspective, int size);

/// An orthographic light's views fitted to what the camera sees: cascades,
/// or one view around every object when the camera sees none.
void fit_orthographic_views(ShadowPlan& plan, const RenderRequest& request, const glm::dmat4& light_view);

}  // namespace umbra

#include "plan/shader_variants.hpp"

namespace umbra {

DisplayVariant without_shadows(const DisplayVariant& v) {
  DisplayVariant lit;
  lit.shadows = false;
  lit.direct_light = v.direct_light;
  lit.shadow_output = v.shadow_output;
  lit.perspective = v.perspective;
  lit.certificates = v.certificates;
  return lit;
}

DisplayVariant display_variant(const RenderRequest& request, const ShadowPlan& plan) {
  DisplayVariant v;
  v.direct_light = plan.direct_light;
  v.shadow_output = request.output == Output::Shadow;
  v.perspective = plan.perspective;
  v.certificates = request.shadow.filter == ShadowFilter::Exact && request.shadow.enabled &&
                   request.output != Output::Depth;
  if (!(request.shadow.enabled && plan.direct_light)) return without_shadows(v);
  const ShadowSettings& s = request.shadow;
  v.cube = plan.layout == ShadowLayout::Cube;
  v.view_count = int(plan.views.size());
  // PCSS with an ideal light (size 0) has no penumbra to find: it is PCF.
  v.filter = s.filter == ShadowFilter::Pcss && request.light.size <= 0.0 ? ShadowFilter::Pcf : s.filter;
  v.pcf_radius = v.filter == ShadowFilter::Pcf ? s.pcf_radius : 0;
  v.bias_auto = s.bias.automatic;
  v.filter_reach = filter_reach_texels(s);
  v.filter_read = filter_read_texels(s);
  return v;
}

}  // namespace umbra

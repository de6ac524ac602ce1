// umbra-cost-report: what the server's cost estimate (renderer/request_cost)
// makes of request bodies, one JSON line per file: the factors, each part's
// milliseconds, the total and the peak bytes, and for filter "exact" the
// three paths' prices (exact_filter_paths) and the one the service takes on
// llvmpipe, and the same on a GPU (exact_filter_paths_on_gpu). Used to calibrate the constants in request_cost.cpp against
// Server-Timing of the same bodies (and Umbra-Certified's path).
//
//   umbra-cost-report body.json...
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>

#include <nlohmann/json.hpp>

#include "service/request_cost.hpp"
#include "request_parser.hpp"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: umbra-cost-report body.json...\n");
    return 2;
  }
  int status = 0;
  for (int i = 1; i < argc; ++i) {
    std::ifstream in(argv[i], std::ios::binary);
    const std::string body((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const umbra::ParsedRequest parsed = umbra::parse_render_request(body);
    if (!parsed.ok()) {
      std::fprintf(stderr, "%s: %s (%s)\n", argv[i], parsed.error.message.c_str(), parsed.error.field.c_str());
      status = 1;
      continue;
    }
    const umbra::RequestCost cost = umbra::estimate_cost(*parsed.request);
    const umbra::CostFactors& f = cost.factors;
    nlohmann::json line = {{"file", argv[i]},
                           {"triangles", f.triangles},
                           {"draws", f.draws},
                           {"shadow_texel_layers", f.shadow_texel_layers},
                           {"shadow_texels", f.shadow_texels},
                           {"pixels", f.pixels},
                           {"gathers_per_pixel", f.gathers_per_pixel},
                           {"pixel_layers", f.pixel_layers},
                           {"mesh_pixel_layers", f.mesh_pixel_layers},
                           {"mesh_texel_layers", f.mesh_texel_layers},
                           {"deepest_mesh", f.deepest_mesh},
                           {"camera_rays", f.camera_rays},
                           {"shadow_rays", f.shadow_rays},
                           {"objects_per_ray", f.objects_per_ray},
                           {"meshes_per_ray", f.meshes_per_ray},
                           {"bvh_triangles", f.bvh_triangles},
                           {"total_ms", cost.total_ms},
                           {"peak_bytes", cost.peak_bytes}};
    for (const auto& part : cost.parts) line["ms"][part.name] = part.ms;
    if (parsed.request->shadow.filter == umbra::ShadowFilter::Exact) {
      // What the service weighs for filter "exact" on llvmpipe, and on a GPU.
      for (const auto& [key, gl] : {std::pair{"exact_filter_paths", umbra::CertifyingGl::Llvmpipe},
                                    std::pair{"exact_filter_paths_on_gpu", umbra::CertifyingGl::Gpu}}) {
        const umbra::ExactFilterPaths paths = umbra::exact_filter_paths(*parsed.request, gl);
        line[key] = {{"maps_ms", paths.maps_ms},
                     {"proofs_ms", paths.proofs_ms},
                     {"ray_cast_ms", paths.ray_cast_ms},
                     {"best", umbra::to_string(paths.best())}};
      }
    }
    std::printf("%s\n", line.dump().c_str());
  }
  return status;
}

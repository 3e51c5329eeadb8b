// Links the installed viscd::tools only: generates a scene, writes its spheres as CSV, reads the
// file back, checks every value survived, and finds the pairs with the detector viscd::tools
// brings along. Usage: tools_consumer FILE.csv
#include <viscd/io.hpp>
#include <viscd/scene.hpp>
#include <viscd/viscd.hpp>

#include <cstddef>
#include <cstdio>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: tools_consumer FILE.csv\n");
    return 2;
  }
  const viscd::Scene scene = viscd::Scene::make({.kind = viscd::SceneKind::box, .objects = 500});
  if (viscd::Status s = viscd::write_spheres_csv(argv[1], scene.spheres()); !s) {
    std::fprintf(stderr, "write_spheres_csv: %s\n", s.error().c_str());
    return 1;
  }
  viscd::Result<std::vector<viscd::Sphere>> read = viscd::read_spheres(argv[1]);
  if (!read) {
    std::fprintf(stderr, "read_spheres: %s\n", read.error().c_str());
    return 1;
  }
  const std::vector<viscd::Sphere>& back = read.value();
  if (back.size() != scene.spheres().size()) {
    std::fprintf(stderr, "read %zu spheres, wrote %zu\n", back.size(), scene.spheres().size());
    return 1;
  }
  for (std::size_t k = 0; k < back.size(); ++k) {
    const viscd::Sphere &a = scene.spheres()[k], &b = back[k];
    if (a.x != b.x || a.y != b.y || a.z != b.z || a.r != b.r) {
      std::fprintf(stderr, "sphere %zu differs after the round trip\n", k);
      return 1;
    }
  }
  viscd::FrameResult frame;
  if (viscd::Status s = viscd::make_cpu_detector()->detect(back, nullptr, frame); !s) {
    std::fprintf(stderr, "detect: %s\n", s.error().c_str());
    return 1;
  }
  std::printf("tools: %zu spheres written and read back, %zu pairs\n", back.size(), frame.pairs.size());
  return 0;
}

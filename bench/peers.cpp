#include "peers.hpp"

#include <utility>

#include "bench_util.hpp"

#include "viscd/detector.hpp"

namespace viscd::bench {
namespace {

class ViscdMethod final : public Method {
 public:
  ViscdMethod(std::string name, int threads) : name_(std::move(name)) {
    Config config = bench_config();
    config.threads = threads;
    detector_ = make_cpu_detector(config);
  }
  [[nodiscard]] std::string_view name() const override { return name_; }
  [[nodiscard]] std::string init(std::span<const Sphere>, const WorldBounds&) override { return ""; }
  [[nodiscard]] bool frame(std::span<const Sphere> spheres, std::span<const Pair>& pairs, std::string& error) override {
    if (Status s = detector_->detect(spheres, nullptr, result_); !s) {
      error = s.error();
      return false;
    }
    pairs = result_.pairs;
    return true;
  }

 private:
  std::string name_;
  std::unique_ptr<Detector> detector_;
  FrameResult result_;  // reused: a steady state allocates nothing
};

}  // namespace

std::unique_ptr<Method> make_viscd_method(std::string name, int threads) {
  return std::make_unique<ViscdMethod>(std::move(name), threads);
}

std::vector<std::string> peer_names() {
  std::vector<std::string> names;
#ifdef VISCD_BENCH_HAVE_BULLET
  names.emplace_back("bullet_dbvt");
  names.emplace_back("bullet_sap");
#endif
#ifdef VISCD_BENCH_HAVE_FCL
  names.emplace_back("fcl_dtree");
#endif
  return names;
}

std::unique_ptr<Method> make_peer(std::string_view name) {
#ifdef VISCD_BENCH_HAVE_BULLET
  if (name == "bullet_dbvt") return make_bullet_dbvt();
  if (name == "bullet_sap") return make_bullet_sap();
#endif
#ifdef VISCD_BENCH_HAVE_FCL
  if (name == "fcl_dtree") return make_fcl_dynamic_tree();
#endif
  (void)name;
  return nullptr;
}

}  // namespace viscd::bench

#include "cpu/wide_tree.hpp"

#include <algorithm>

#include "cpu/grow.hpp"
#include "cpu/parallel.hpp"

namespace viscd::detail {
namespace {

// Node counts level by level over `leaves`: ceil(count / 16) until one node is left.
std::uint32_t level_count(std::size_t leaves) {
  if (leaves == 0) return 0;
  std::uint32_t levels = 1;
  for (std::size_t nodes = (leaves + kWide - 1) / kWide; nodes > 1; nodes = (nodes + kWide - 1) / kWide) ++levels;
  return levels;
}

}  // namespace

void build_wide_tree(std::span<const Aabb> leaf_boxes, WideTree& tree, int threads) {
  tree.leaves = leaf_boxes.size();
  tree.levels = level_count(leaf_boxes.size());
  if (tree.level.size() < tree.levels) tree.level.resize(tree.levels);
  std::size_t entries = leaf_boxes.size();  // children of this level's nodes
  for (std::uint32_t k = 0; k < tree.levels; ++k) {
    const std::size_t nodes = (entries + kWide - 1) / kWide;
    std::vector<WideNode>& level = tree.level[k];
    resize_with_headroom(level, nodes);
    const std::vector<WideNode>* below = k ? &tree.level[k - 1] : nullptr;
    parallel_for(nodes, threads, [&](std::size_t j) {
      WideNode& n = level[j];
      for (std::uint32_t l = 0; l < kWide; ++l) {
        const std::size_t c = j * kWide + l;
        n.set_child(l, c >= entries ? Aabb{} : below ? (*below)[c].box() : leaf_boxes[c]);
      }
    });
    entries = nodes;
  }
}

std::string validate_wide_tree(const WideTree& tree, std::span<const Aabb> leaf_boxes) {
  auto same = [](const Aabb& a, const Aabb& b) {
    return a.lo.x == b.lo.x && a.lo.y == b.lo.y && a.lo.z == b.lo.z && a.hi.x == b.hi.x && a.hi.y == b.hi.y &&
           a.hi.z == b.hi.z;
  };
  if (tree.leaves != leaf_boxes.size()) return "leaf count differs from the leaf boxes";
  if (tree.levels != level_count(leaf_boxes.size())) return "wrong number of levels";
  if (tree.levels > kWideMaxLevels) return "more levels than the walk's stack holds";
  std::size_t entries = leaf_boxes.size();
  for (std::uint32_t k = 0; k < tree.levels; ++k) {
    const std::size_t nodes = (entries + kWide - 1) / kWide;
    if (tree.level[k].size() != nodes) return "level " + std::to_string(k) + " has the wrong node count";
    if (k + 1 == tree.levels && nodes != 1) return "the top level is not one node";
    for (std::size_t j = 0; j < nodes; ++j)
      for (std::uint32_t l = 0; l < kWide; ++l) {
        const std::size_t c = j * kWide + l;
        const Aabb want = c >= entries ? Aabb{} : k == 0 ? leaf_boxes[c] : tree.level[k - 1][c].box();
        if (!same(tree.level[k][j].child(l), want))
          return "level " + std::to_string(k) + " node " + std::to_string(j) + " child " + std::to_string(l) +
                 (c >= entries ? " is not empty" : " is not the box of what it covers");
      }
    entries = nodes;
  }
  return {};
}

}  // namespace viscd::detail

#include "core/lbvh.hpp"

#include <algorithm>

namespace viscd::detail {

std::string validate_lbvh(const Lbvh& bvh, std::span<const Aabb> leaf_boxes) {
  const std::size_t n = bvh.leaves;
  if (leaf_boxes.size() != n) return "leaf box count differs from leaf count";
  if (n < 2) return bvh.nodes.empty() ? "" : "a tree of fewer than two leaves has internal nodes";
  if (bvh.nodes.size() != n - 1) return "internal node count is not leaves - 1";
  std::vector<std::uint8_t> seen_leaf(n, 0), seen_node(n - 1, 0);
  // Iterative DFS from the root computing each subtree's box and last position.
  std::vector<std::uint32_t> stack{0};
  seen_node[0] = 1;
  if (bvh.parent[0] != kNoParent) return "root has a parent";
  // Post-order needs subtree results; compute boxes by recursion over an explicit order.
  std::vector<std::uint32_t> order;
  order.reserve(n - 1);
  while (!stack.empty()) {
    const std::uint32_t node = stack.back();
    stack.pop_back();
    order.push_back(node);
    const BvhNode& nd = bvh.nodes[node];
    for (int c = 0; c < 2; ++c) {
      const std::uint32_t ch = nd.child[c];
      if (ch & kLeafBit) {
        const std::uint32_t leaf = ch & ~kLeafBit;
        if (leaf >= n) return "leaf id out of range at node " + std::to_string(node);
        if (seen_leaf[leaf]++) return "leaf " + std::to_string(leaf) + " appears twice";
        if (bvh.leaf_parent[leaf] != node) return "leaf " + std::to_string(leaf) + " has a wrong parent link";
      } else {
        if (ch >= n - 1) return "child id out of range at node " + std::to_string(node);
        if (seen_node[ch]++) return "internal node " + std::to_string(ch) + " reached twice";
        if (bvh.parent[ch] != node) return "node " + std::to_string(ch) + " has a wrong parent link";
        stack.push_back(ch);
      }
    }
  }
  for (std::size_t p = 0; p < n; ++p)
    if (!seen_leaf[p]) return "leaf " + std::to_string(p) + " is not in the tree";
  for (std::size_t i = 0; i < n - 1; ++i)
    if (!seen_node[i]) return "internal node " + std::to_string(i) + " is not in the tree";
  // Bottom-up over the reversed pre-order: children are handled before their parents.
  std::vector<Aabb> box(n - 1);
  std::vector<std::uint32_t> last(n - 1);
  for (auto it = order.rbegin(); it != order.rend(); ++it) {
    const BvhNode& nd = bvh.nodes[*it];
    Aabb b;
    std::uint32_t l = 0;
    for (int c = 0; c < 2; ++c) {
      const std::uint32_t ch = nd.child[c];
      const Aabb& cb = (ch & kLeafBit) ? leaf_boxes[ch & ~kLeafBit] : box[ch];
      const std::uint32_t cl = (ch & kLeafBit) ? (ch & ~kLeafBit) : last[ch];
      if (!nd.box[c].contains(cb))
        return "box of child " + std::to_string(c) + " of node " + std::to_string(*it) +
               " does not contain its subtree";
      if (nd.last[c] != cl)
        return "last position of child " + std::to_string(c) + " of node " + std::to_string(*it) + " is wrong";
      b.grow(cb);
      l = std::max(l, cl);
    }
    box[*it] = b;
    last[*it] = l;
  }
  if (!bvh.root_box.contains(box[0])) return "root box does not contain the tree";
  return "";
}

int lbvh_depth(const Lbvh& bvh) {
  if (bvh.leaves < 2) return 0;
  int deepest = 0;
  std::vector<std::pair<std::uint32_t, int>> stack{{0u, 0}};
  while (!stack.empty()) {
    auto [node, d] = stack.back();
    stack.pop_back();
    for (std::uint32_t ch : bvh.nodes[node].child) {
      if (ch & kLeafBit)
        deepest = std::max(deepest, d + 1);
      else
        stack.push_back({ch, d + 1});
    }
  }
  return deepest;
}

}  // namespace viscd::detail

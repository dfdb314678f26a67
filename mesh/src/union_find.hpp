#pragma once
// Disjoint sets over 0..n-1 (internal to mesh/): the smallest index of a set is its root, so the
// result does not depend on the order of unions.
#include <algorithm>
#include <numeric>
#include <vector>

namespace lambert::mesh::detail {

struct UnionFind {
  std::vector<int> parent;
  UnionFind() = default;
  explicit UnionFind(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int add() {  // a new singleton; returns its index
    parent.push_back(static_cast<int>(parent.size()));
    return parent.back();
  }
  int find(int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void unite(int a, int b) {
    a = find(a), b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

}  // namespace lambert::mesh::detail

// Scene bundles (.sgdb): the format is specified in src/segadeform/bundle.py and docs/package.md.
#pragma once
#include <cctype>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "json.hpp"

namespace sgd {

struct Array {
  std::string dtype;
  std::vector<int64_t> shape;
  std::vector<uint8_t> bytes;
  int64_t count() const {
    int64_t n = 1;
    for (auto d : shape) n *= d;
    return n;
  }
  template <class T> const T* as() const { return reinterpret_cast<const T*>(bytes.data()); }
};

struct Bundle {
  std::map<std::string, Array> arrays;
  Json meta;
  const Array& at(const std::string& k) const {
    auto it = arrays.find(k);
    if (it == arrays.end()) throw std::runtime_error("bundle has no array '" + k + "'");
    return it->second;
  }
  bool has(const std::string& k) const { return arrays.count(k) > 0; }
};

// What to make of a file that is not a bundle, by its extension: a mesh or a motion these runtimes cannot read.
inline std::string not_bundle_hint(const std::string& path) {
  const size_t dot = path.find_last_of('.');
  const size_t slash = path.find_last_of("/\\");
  std::string ext = (dot == std::string::npos || (slash != std::string::npos && dot < slash)) ? "" : path.substr(dot);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const char* m : {".obj", ".ply", ".stl", ".off", ".mhclo"})
    if (ext == m) return " (a mesh: these runtimes read a garment asset, `segadeform garment export GARMENT -o G.sgda`)";
  for (const char* m : {".bvh", ".amc", ".npz", ".glb", ".gltf", ".fbx"})
    if (ext == m) return " (a motion file: these runtimes read one made by `segadeform motion export MOTION -o M.sgdm`)";
  return "";
}

inline Bundle read_bundle(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path + ": no such file");
  std::string data((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const std::string magic = "SEGADEFORM-BUNDLE 1\n";
  if (data.compare(0, magic.size(), magic) != 0) throw std::runtime_error(path + ": not a segadeform bundle" + not_bundle_hint(path));
  size_t end = data.find("\nEND\n");
  if (end == std::string::npos) throw std::runtime_error(path + ": bundle header has no END line");
  size_t start = ((end + 5 + 63) / 64) * 64;
  std::istringstream head(data.substr(magic.size(), end - magic.size()));
  std::string line;
  std::getline(head, line);
  int n = std::stoi(line);
  Bundle b;
  static const std::map<std::string, int> sizes = {{"f32", 4}, {"f64", 8}, {"i32", 4}, {"i64", 8}, {"u8", 1}};
  for (int i = 0; i < n; ++i) {
    std::getline(head, line);
    std::istringstream t(line);
    std::string name, dt;
    int nd;
    t >> name >> dt >> nd;
    Array a;
    a.dtype = dt;
    for (int k = 0; k < nd; ++k) { int64_t d; t >> d; a.shape.push_back(d); }
    int64_t off, nbytes;
    t >> off >> nbytes;
    auto sz = sizes.find(dt);
    if (!t || sz == sizes.end() || a.count() * sz->second != nbytes ||
        static_cast<int64_t>(start) + off + nbytes > static_cast<int64_t>(data.size()))
      throw std::runtime_error(path + ": bundle array " + name + " does not fit the file");
    a.bytes.assign(data.begin() + start + off, data.begin() + start + off + nbytes);
    b.arrays[name] = std::move(a);
  }
  std::getline(head, line);
  if (line.compare(0, 5, "meta ") != 0) throw std::runtime_error(path + ": malformed bundle header");
  b.meta = parse_json(line.substr(5));
  return b;
}

}  // namespace sgd

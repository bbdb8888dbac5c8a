// Scene bundles (.sgdb): the format is specified in src/segadeform/bundle.py and docs/package.md.
#pragma once
#include <cctype>
#include <cstdint>
#include <cstring>
#include <filesystem>
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
  int64_t count() const {  // the shape's product (read_bundle holds every array to the file's size)
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

namespace bundle_detail {
// A whole decimal integer of `text` in [lo, hi], else the error `what`
inline int64_t integer(const std::string& text, int64_t lo, int64_t hi, const std::string& what) {
  size_t k = 0;
  int64_t v = 0;
  try {
    v = std::stoll(text, &k);
  } catch (const std::exception&) {
    throw std::runtime_error(what);
  }
  if (k != text.size() || v < lo || v > hi) throw std::runtime_error(what);
  return v;
}
}  // namespace bundle_detail

inline Bundle read_bundle_unchecked(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw std::runtime_error(path + ": is a directory, not a file");
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path + ": no such file");
  std::string data((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const std::string magic = "SEGADEFORM-BUNDLE 1\n";
  if (data.compare(0, magic.size(), magic) != 0) throw std::runtime_error(path + ": not a segadeform bundle" + not_bundle_hint(path));
  size_t end = data.find("\nEND\n");
  if (end == std::string::npos) throw std::runtime_error(path + ": bundle header has no END line");
  const int64_t start = static_cast<int64_t>(((end + 5 + 63) / 64) * 64);
  const int64_t body = static_cast<int64_t>(data.size()) - start;  // bytes of array data (negative: none)
  std::istringstream head(data.substr(magic.size(), end - magic.size()));
  std::string line;
  std::getline(head, line);
  const std::string malformed = path + ": malformed bundle header";
  const int64_t n = bundle_detail::integer(line, 0, 100000, malformed + " (expected the number of arrays)");
  Bundle b;
  static const std::map<std::string, int> sizes = {{"f32", 4}, {"f64", 8}, {"i32", 4}, {"i64", 8}, {"u8", 1}};
  for (int64_t i = 0; i < n; ++i) {
    std::getline(head, line);
    std::istringstream t(line);
    std::vector<std::string> w;
    for (std::string x; t >> x;) w.push_back(x);
    if (w.size() < 5) throw std::runtime_error(malformed + " (expected NAME DTYPE NDIM DIMS... OFFSET NBYTES)");
    const std::string& name = w[0];
    const std::string fits = path + ": bundle array " + name + " does not fit the file";
    Array a;
    a.dtype = w[1];
    auto sz = sizes.find(a.dtype);
    if (sz == sizes.end()) throw std::runtime_error(path + ": bundle array " + name + " has an unknown dtype " + a.dtype);
    const int64_t nd = bundle_detail::integer(w[2], 0, 8, fits);
    if (static_cast<int64_t>(w.size()) != 5 + nd) throw std::runtime_error(fits);
    // every size checked against the file before any product or allocation (no overflow, nothing past its end)
    const int64_t limit = body > 0 ? body : 0;
    int64_t count = 1;
    for (int64_t k = 0; k < nd; ++k) {
      const int64_t d = bundle_detail::integer(w[3 + k], 0, limit, fits);
      a.shape.push_back(d);
      if (d != 0 && count > limit / d) count = limit + 1;  // more elements than the file holds bytes
      else count *= d;
    }
    const int64_t off = bundle_detail::integer(w[3 + nd], 0, limit, fits);
    const int64_t nbytes = bundle_detail::integer(w[4 + nd], 0, limit, fits);
    if (body < 0 || count > limit || count * sz->second != nbytes || off > limit - nbytes)  // (body < 0: no data
      throw std::runtime_error(fits);                                                       // at all, not even 0 B)
    a.bytes.assign(data.begin() + start + off, data.begin() + start + off + nbytes);
    b.arrays[name] = std::move(a);
  }
  std::getline(head, line);
  if (line.compare(0, 5, "meta ") != 0) throw std::runtime_error(malformed);
  b.meta = parse_json(line.substr(5));
  return b;
}

// The bundle at `path`; any problem reading it is one std::runtime_error naming the file (a crafted or damaged file
// threw std::invalid_argument from stoi, or read out of bounds, before)
inline Bundle read_bundle(const std::string& path) {
  try {
    return read_bundle_unchecked(path);
  } catch (const std::exception& e) {
    const std::string what = e.what();
    if (what.compare(0, path.size() + 1, path + ":") == 0) throw std::runtime_error(what);
    throw std::runtime_error(path + ": unreadable bundle (" + what + ")");
  }
}

}  // namespace sgd

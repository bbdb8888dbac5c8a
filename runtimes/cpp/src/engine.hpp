// The C++ runtime's engine, shared by segadeform-run (main.cpp) and the library's segadeform::Player (player.cpp):
// the onnxruntime C API sessions, the package manifest, the checked inputs of a scene (a garment asset with a
// motion file, or a scene bundle) and the Stream that plays a motion pushed a chunk at a time -- the deformer over
// the motion window, the body posed by the package's body graph, then the cloth stage or collisions -- with its
// state carried between chunks.  Internal: a program of one's own includes <segadeform/player.hpp> instead.
#pragma once
#include <onnxruntime_c_api.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#ifdef __linux__
#include <sched.h>
#endif

#include "bundle.hpp"
#include "cloth.hpp"
#include "collide.hpp"
#include "json.hpp"
#include "outputs.hpp"

namespace sgd {
namespace engine {

inline const OrtApi* api = nullptr;  // set by the first user (ort_api())

inline void check(OrtStatus* s) {
  if (s) {
    std::string msg = api->GetErrorMessage(s);
    api->ReleaseStatus(s);
    throw std::runtime_error("onnxruntime: " + msg);
  }
}

// `asked` threads, at most the CPUs this process may use (its affinity on Linux: a container's share): more only
// contend (1000 took about 6 s a frame: a user's trial).  Python's and Node's command lines lower it alike.
inline int usable_threads(int asked) {
  int cpus = static_cast<int>(std::thread::hardware_concurrency());
#ifdef __linux__
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0) cpus = CPU_COUNT(&set);
#endif
  return std::min(asked, std::max(1, cpus));
}

inline std::string read_text(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path + ": no such file");
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

// One owned input tensor: its storage and the OrtValue over it.
struct Input {
  std::string name;
  std::vector<uint8_t> data;
  std::vector<int64_t> dims;
  OrtValue* value = nullptr;
};

inline ONNXTensorElementDataType ort_type(const std::string& dtype) {
  if (dtype == "float32") return ONNX_TENSOR_ELEMENT_DATA_TYPE_FLOAT;
  if (dtype == "int64") return ONNX_TENSOR_ELEMENT_DATA_TYPE_INT64;
  if (dtype == "int32") return ONNX_TENSOR_ELEMENT_DATA_TYPE_INT32;
  if (dtype == "bool") return ONNX_TENSOR_ELEMENT_DATA_TYPE_BOOL;
  throw std::runtime_error("unsupported input dtype " + dtype);
}

inline size_t elem_size(const std::string& dtype) {
  if (dtype == "int64") return 8;
  if (dtype == "bool") return 1;
  return 4;
}

// Converts a bundle array (f32, i32 or u8) to the dtype the graph input wants.
inline std::vector<uint8_t> convert(const sgd::Array& a, const std::string& dtype) {
  int64_t n = a.count();
  std::vector<uint8_t> out(static_cast<size_t>(n) * elem_size(dtype));
  for (int64_t i = 0; i < n; ++i) {
    double v = a.dtype == "f32" ? a.as<float>()[i] : a.dtype == "i32" ? a.as<int32_t>()[i]
             : a.dtype == "u8" ? a.as<uint8_t>()[i] : a.dtype == "i64" ? static_cast<double>(a.as<int64_t>()[i])
             : a.as<double>()[i];
    if (dtype == "float32") { float f = static_cast<float>(v); std::memcpy(&out[i * 4], &f, 4); }
    else if (dtype == "int64") { int64_t k = static_cast<int64_t>(v); std::memcpy(&out[i * 8], &k, 8); }
    else if (dtype == "int32") { int32_t k = static_cast<int32_t>(v); std::memcpy(&out[i * 4], &k, 4); }
    else out[i] = v != 0;
  }
  return out;
}

// One output of a run: floats (float32 outputs) or ints (int32 outputs), and the shape.
struct Output {
  std::vector<float> f;
  std::vector<int32_t> i;
  std::vector<int64_t> shape;
};

class Session {
 public:
  // `arena`: onnxruntime's CPU memory arena, which keeps a run's peak for the session's life: off for the encoder
  // (it runs once per garment), as segadeform run has it.  Over one thread, idle pool threads sleep instead of
  // spinning, as segadeform run has them (spinning threads took the cores the rest of the run needs: 2 threads ran
  // at half the speed of 1).
  Session(OrtEnv* env, const std::string& path, int threads, bool arena = true) {
    OrtSessionOptions* so;
    check(api->CreateSessionOptions(&so));
    OrtStatus* st = api->SetIntraOpNumThreads(so, threads);
    if (!st) st = api->SetInterOpNumThreads(so, 1);
    if (!st && !arena) st = api->DisableCpuMemArena(so);
    if (!st && threads > 1) st = api->AddSessionConfigEntry(so, "session.intra_op.allow_spinning", "0");
    if (!st) st = api->CreateSession(env, path.c_str(), so, &s_);
    api->ReleaseSessionOptions(so);
    check(st);
  }
  ~Session() { if (s_) api->ReleaseSession(s_); }
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  // Runs with named inputs; returns the named outputs (float32 or int32) with their shapes.
  std::vector<Output> run(std::vector<Input>& ins, const std::vector<std::string>& out_names) {
    std::vector<const char*> names;
    std::vector<OrtValue*> values;
    for (auto& in : ins) {
      if (!in.value) throw std::runtime_error("input '" + in.name + "' has no value");
      names.push_back(in.name.c_str());
      values.push_back(in.value);
    }
    std::vector<const char*> on;
    for (const auto& n : out_names) on.push_back(n.c_str());
    std::vector<OrtValue*> outs(on.size(), nullptr);
    check(api->Run(s_, nullptr, names.data(), values.data(), values.size(), on.data(), on.size(), outs.data()));
    std::vector<Output> r(outs.size());
    for (size_t k = 0; k < outs.size(); ++k) {
      OrtTensorTypeAndShapeInfo* info;
      check(api->GetTensorTypeAndShape(outs[k], &info));
      size_t nd, count;
      ONNXTensorElementDataType type;
      check(api->GetDimensionsCount(info, &nd));
      r[k].shape.resize(nd);
      check(api->GetDimensions(info, r[k].shape.data(), nd));
      check(api->GetTensorShapeElementCount(info, &count));
      check(api->GetTensorElementType(info, &type));
      api->ReleaseTensorTypeAndShapeInfo(info);
      void* p;
      check(api->GetTensorMutableData(outs[k], &p));
      if (type == ONNX_TENSOR_ELEMENT_DATA_TYPE_FLOAT) r[k].f.assign(static_cast<float*>(p), static_cast<float*>(p) + count);
      else if (type == ONNX_TENSOR_ELEMENT_DATA_TYPE_INT32)
        r[k].i.assign(static_cast<int32_t*>(p), static_cast<int32_t*>(p) + count);
      else throw std::runtime_error("output '" + out_names[k] + "' is neither float32 nor int32");
      api->ReleaseValue(outs[k]);
    }
    return r;
  }
  OrtSession* s_ = nullptr;
};

// Inputs get their element type at creation: a small helper making the OrtValue eagerly.
inline void make_value(Input& in, const std::string& dtype) {
  OrtMemoryInfo* mem;
  check(api->CreateCpuMemoryInfo(OrtArenaAllocator, OrtMemTypeDefault, &mem));
  check(api->CreateTensorWithDataAsOrtValue(mem, in.data.data(), in.data.size(), in.dims.data(), in.dims.size(),
                                            ort_type(dtype), &in.value));
  api->ReleaseMemoryInfo(mem);
}

inline void release(std::vector<Input>& ins) {
  for (auto& in : ins) if (in.value) { api->ReleaseValue(in.value); in.value = nullptr; }
}

inline const sgd::Json& find_input(const sgd::Json& spec, const std::string& name) {
  for (const auto& i : spec["inputs"].arr) if (i["name"].str == name) return i;
  throw std::runtime_error("graph has no input '" + name + "'");
}

inline bool has_input(const sgd::Json& spec, const std::string& name) {
  for (const auto& i : spec["inputs"].arr) if (i["name"].str == name) return true;
  return false;
}

// An input in the dtype the graph's manifest entry names (schema 3: int32 indices and float32 masks; schema 2:
// int64 and bool), from a container array of any dtype.
inline Input input_from(const sgd::Json& spec, const std::string& name, const sgd::Array& a, std::vector<int64_t> dims) {
  const std::string dtype = find_input(spec, name)["dtype"].str;
  Input in{name, convert(a, dtype), std::move(dims)};
  make_value(in, dtype);
  return in;
}

inline Input input_floats(const std::string& name, std::vector<float> v, std::vector<int64_t> dims) {
  Input in{name, std::vector<uint8_t>(v.size() * 4), std::move(dims)};
  std::memcpy(in.data.data(), v.data(), in.data.size());
  make_value(in, "float32");
  return in;
}

// A container array as float32 values (f32, f64, i32 or u8).
// Throw unless every value of a float array is finite (field `name` of file `where`; other dtypes pass).
inline void finite_values(const sgd::Array& a, const std::string& where, const std::string& name) {
  int64_t bad = -1;  // the first value that is not finite, named by its index (a motion's poses: [frame, joint, axis])
  if (a.dtype == "f32") {
    const float* d = a.as<float>();
    for (int64_t i = 0; i < a.count() && bad < 0; ++i)
      if (!std::isfinite(d[i])) bad = i;
  } else if (a.dtype == "f64") {
    const double* d = a.as<double>();
    for (int64_t i = 0; i < a.count() && bad < 0; ++i)
      if (!std::isfinite(d[i])) bad = i;
  }
  if (bad < 0) return;
  std::string index;
  for (size_t k = a.shape.size(); k-- > 0;) {
    index = std::to_string(bad % a.shape[k]) + (index.empty() ? "" : ", ") + index;
    bad /= a.shape[k];
  }
  throw std::runtime_error(where + ": field '" + name + "' contains NaN or inf (first at index [" + index + "])");
}

// The same rotations with every angle in [0, pi] (Python's canonical_axis_angle, segadeform.body.rotations): an
// angle above pi is taken modulo 2 pi, one still above pi becomes 2 pi minus it about the opposite axis; a vector in
// range is left bit for bit.  In place on axis-angle triples, computed in double as Python computes them.
inline void canonical_axis_angle(float* r, size_t n) {
  const double pi = 3.141592653589793;
  for (size_t i = 0; i + 2 < n; i += 3) {
    const double x = r[i], y = r[i + 1], z = r[i + 2];
    const double t = std::sqrt(x * x + y * y + z * z);
    if (!(t > pi)) continue;
    double a = std::fmod(t, 2 * pi), sgn = 1.0;
    if (a > pi) a = 2 * pi - a, sgn = -1.0;
    r[i] = static_cast<float>((sgn * x / t) * a);
    r[i + 1] = static_cast<float>((sgn * y / t) * a);
    r[i + 2] = static_cast<float>((sgn * z / t) * a);
  }
}
inline void canonical_axis_angle(std::vector<float>& r) { canonical_axis_angle(r.data(), r.size()); }

inline std::vector<float> floats(const sgd::Array& a) {
  std::vector<uint8_t> b = convert(a, "float32");
  std::vector<float> out(b.size() / 4);
  std::memcpy(out.data(), b.data(), b.size());
  return out;
}

// `path`'s PC2 point cache of T frames of N points, written to its temporary (sgd::temporary; sgd::commit_outputs
// puts it in place) a batch of frames at a time: append() the frames in order, then finish().
class Pc2Writer {
 public:
  Pc2Writer(const std::string& path, int32_t T, int32_t N, float start = 0.f)
      : path_(path), tmp_(sgd::temporary(path)), f_(tmp_, std::ios::binary), left_(static_cast<int64_t>(T) * N * 3) {
    if (!f_) throw std::runtime_error(path + ": cannot write");
    f_.write("POINTCACHE2\0", 12);
    const int32_t version = 1;
    const float rate = 1.f;
    f_.write(reinterpret_cast<const char*>(&version), 4);
    f_.write(reinterpret_cast<const char*>(&N), 4);
    f_.write(reinterpret_cast<const char*>(&start), 4);
    f_.write(reinterpret_cast<const char*>(&rate), 4);
    f_.write(reinterpret_cast<const char*>(&T), 4);
    check_stream();
  }
  // `count` floats (whole frames), the next ones of the cache
  void append(const float* values, int64_t count) {
    if (count > left_) throw std::runtime_error(path_ + ": more frames than the cache's header says");
    f_.write(reinterpret_cast<const char*>(values), static_cast<std::streamsize>(sizeof(float) * count));
    left_ -= count;
    check_stream();
  }
  void finish() {
    if (left_ != 0) throw std::runtime_error(path_ + ": fewer frames than the cache's header says");
    f_.close();
    check_stream();
  }

 private:
  void check_stream() {
    if (!f_) {
      f_.close();
      std::remove(tmp_.c_str());
      throw std::runtime_error(path_ + ": write failed");
    }
  }
  std::string path_, tmp_;
  std::ofstream f_;
  int64_t left_;
};


struct Effects {
  std::string skinning = "lbs";
  bool wrinkles = false, dynamics = false, collisions = false, cloth = false;
};

// segadeform.scene.Effects.collision_margin's default (metres)
inline const double DEFAULT_COLLISION_MARGIN = 0.004;
// the most vertex-frames (batch x garment vertices) one deformer call takes: a bigger garment runs fewer frames a
// call, as segadeform run does (runtimes/python/pipeline.py MAX_VERTEX_FRAMES; at 69k vertices batch 8 took 7 GB
// and its frames were not segadeform run's)
inline const int64_t MAX_VERTEX_FRAMES = 32768;

// Frames per deformer call for a garment of n vertices: batch, lowered (to at least 1) so that batch x n <=
// MAX_VERTEX_FRAMES.
inline int effective_batch(int batch, int64_t n) {
  return static_cast<int>(std::max<int64_t>(1, std::min<int64_t>(batch, MAX_VERTEX_FRAMES / std::max<int64_t>(n, 1))));
}

// --effects: a complete list, as `segadeform run --effects` (what is not named is off; lbs unless dqs is named).
// Effects as `segadeform run --effects` reads them (src/segadeform/settings/effects.py): a complete list such as
// "dqs,dynamics,wrinkles,collisions" (what is not named is off; lbs unless dqs is named), "none" (every effect off),
// or signed changes to `base` (the run's default effects) such as "+cloth" or "dqs,-wrinkles".
inline Effects parse_effects(const std::string& text, const Effects& base) {
  std::vector<std::string> items;
  {
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
      const size_t a = item.find_first_not_of(" \t"), b = item.find_last_not_of(" \t");
      if (a != std::string::npos) items.push_back(item.substr(a, b - a + 1));
    }
  }
  if (items.empty())
    throw std::runtime_error("an empty effects list (expected effect names, signed changes (+name,-name) or none, got \"" +
                             text + "\")");
  Effects off;
  off.skinning = "lbs";
  if (items.size() == 1 && items[0] == "none") return off;
  std::vector<std::string> picked, named;
  for (const auto& i : items) (i == "lbs" || i == "dqs" ? picked : named).push_back(i);
  size_t n_signed = 0;
  for (const auto& i : named) n_signed += (i[0] == '+' || i[0] == '-');
  if (n_signed && n_signed != named.size())
    throw std::runtime_error("effects mix a complete list with changes (expected names only or signed changes only, "
                             "got " + text + ")");
  const bool complete = n_signed == 0;
  std::vector<std::string> seen;
  for (const auto& i : named) {
    const std::string name = (i[0] == '+' || i[0] == '-') ? i.substr(1) : i;
    if (std::find(seen.begin(), seen.end(), name) != seen.end())
      throw std::runtime_error("effects name " + name + " twice (expected each effect once, got " + text + ")");
    seen.push_back(name);
  }
  Effects e = complete ? off : base;
  for (const auto& i : named) {
    const bool on = i[0] != '-';
    const std::string name = (i[0] == '+' || i[0] == '-') ? i.substr(1) : i;
    if (name == "dynamics") e.dynamics = on;
    else if (name == "wrinkles") e.wrinkles = on;
    else if (name == "collisions") e.collisions = on;
    else if (name == "cloth") e.cloth = on;
    else
      throw std::runtime_error("unknown effect '" + i + "' (expected lbs, dqs, [+-]dynamics, [+-]wrinkles, "
                               "[+-]collisions, [+-]cloth or none)");
  }
  const bool lbs = std::find(picked.begin(), picked.end(), "lbs") != picked.end();
  const bool dqs = std::find(picked.begin(), picked.end(), "dqs") != picked.end();
  if (lbs && dqs) throw std::runtime_error("name one skinning (expected lbs or dqs, got both)");
  if (picked.size() > 1)
    throw std::runtime_error("effects name " + picked.front() + " twice (expected each effect once, got " + text + ")");
  e.skinning = !picked.empty() ? picked.back() : complete ? "lbs" : base.skinning;
  return e;
}

inline Effects effects_of(const sgd::Json& e) {
  Effects r;
  r.skinning = e["skinning"].str;
  r.wrinkles = e["wrinkles"].b;
  r.dynamics = e["dynamics"].b;
  return r;
}

// The manifest, checked: schema 1, 2 or 3 (docs/package.md).
struct Package {
  std::string dir;
  sgd::Json manifest;
  int schema = 0;

  explicit Package(const std::string& d) : dir(d), manifest(sgd::parse_json(read_text(d + "/manifest.json"))) {
    if (!manifest.has("format") || manifest["format"].str != "segadeform-model-package")
      throw std::runtime_error(dir + ": not a segadeform model package");
    const double v = manifest.has("schema_version") ? manifest["schema_version"].num : 0.0;
    schema = v == 1.0 || v == 2.0 || v == 3.0 ? static_cast<int>(v) : 0;  // (a cast of NaN or 1e300 is undefined)
    if (schema == 0)
      throw std::runtime_error(dir + "/manifest.json: unsupported manifest schema version (expected 1, 2 or 3)");
  }
  // a graph's file: a plain .onnx name in the package folder, as Python's manifest schema has it (a name with a path
  // in it loaded a graph from outside the package, or waited on a FIFO: a security review)
  std::string graph_file(const sgd::Json& spec) const {
    const std::string f = spec.has("file") ? spec["file"].str : std::string();
    const bool plain = f.size() > 5 && f[0] != '.' && f.find('/') == std::string::npos &&
                       f.find('\\') == std::string::npos && f.compare(f.size() - 5, 5, ".onnx") == 0;
    if (!plain)
      throw std::runtime_error(dir + "/manifest.json: a graph's file must be a .onnx file name in the package folder "
                               "(got \"" + f + "\")");
    return dir + "/" + f;
  }
  // schema 1 listed the deformers in "variants"; 2 and 3 list every graph once in "graphs", with a role
  const sgd::Json& deformer(const Effects& want) const {
    for (const auto& kv : (schema == 1 ? manifest["variants"] : manifest["graphs"]).obj) {
      if (schema > 1 && (!kv.second.has("role") || kv.second["role"].str != "deformer")) continue;
      const auto& e = kv.second["effects"];
      if (e["skinning"].str == want.skinning && e["wrinkles"].b == want.wrinkles && e["dynamics"].b == want.dynamics)
        return kv.second;
    }
    size_t n = 0;
    for (const auto& kv : (schema == 1 ? manifest["variants"] : manifest["graphs"]).obj)
      if (schema == 1 || (kv.second.has("role") && kv.second["role"].str == "deformer")) ++n;
    throw std::runtime_error("the package has no deformer graph for effects " + want.skinning +
                             (want.dynamics ? ", dynamics" : "") + (want.wrinkles ? ", wrinkles" : "") +
                             (n == 1 ? " (it has the model's own alone: `segadeform export` without --no-variants "
                                       "writes the others)"
                                     : ""));
  }
  // the effects of a run that names none: the model's own and collisions when the package can pose the body
  Effects default_effects() const {
    if (schema == 1) {
      const auto& c = manifest["config"];
      Effects e;
      e.skinning = c["skinning"].str;
      e.wrinkles = c["use_blend_shapes"].b;
      e.dynamics = true;
      return e;
    }
    Effects e = effects_of(manifest["graphs"][manifest["default_deformer"].str]["effects"]);
    e.collisions = has_body();
    return e;
  }
  bool has_body() const {
    if (schema < 3) return false;
    for (const auto& kv : manifest["graphs"].obj)
      if (kv.second.has("role") && kv.second["role"].str == "body") return true;
    return false;
  }
  // the body graph posing with `skinning`, or nullptr when the package has none (packages before schema 3)
  const sgd::Json* body(const std::string& skinning) const {
    if (schema < 3) return nullptr;
    bool any = false;
    for (const auto& kv : manifest["graphs"].obj) {
      if (!kv.second.has("role") || kv.second["role"].str != "body") continue;
      any = true;
      if (kv.second["skinning"].str == skinning) return &kv.second;
    }
    if (any) throw std::runtime_error("the package has no body graph for skinning " + skinning);
    return nullptr;
  }
};

// The model inputs of one scene: from a bundle, or from a garment asset and a motion file.
struct Scene {
  const sgd::Array *features = nullptr, *nbr = nullptr, *mask = nullptr, *descriptor = nullptr, *joints = nullptr,
                   *log_wbody = nullptr;
  std::vector<float> rest, betas, poses, trans;
  // N: the garment the frames are written, collided and stepped on; M: the model's garment (rest, features, nbr ...),
  // a decimated copy of it in a schema-3 asset (garment export --resolution), else the same (M = N)
  int64_t N = 0, M = 0, K = 0, S = 0, T = 0, D = 0;
  // a schema-3 asset's map from the model's garment to the garment as given: each given vertex's triangle of
  // `model_faces`, barycentric weights and offset along its unit normal (segadeform.body.resample.SurfaceMap)
  const sgd::Array *carry_face = nullptr, *carry_bary = nullptr, *carry_offset = nullptr, *model_faces = nullptr;
  std::string body_sha;  // the body a garment asset was prepared for
  std::string weight_prior;  // how its weights reached the garment (log_wbody): nearest | inpaint
  const sgd::Array *vertices64 = nullptr, *faces = nullptr;  // a garment asset's rest vertices and faces (cloth)
  double fps = 0;  // a motion file's frame rate
  float start_frame = 0.f;  // a motion file's first frame number in its source (motion export --frames A:B: A)
  std::vector<std::string> warnings;  // what a forced run played anyway (the caller says them)
};

inline const sgd::Array& need(const sgd::Bundle& b, const std::string& path, const std::string& name, const std::string& dtype,
                       size_t ndim);

// a scene bundle's arrays, checked as an asset's are: dtypes, ranks, agreeing shapes and index ranges (a bundle with a
// 1-D nbr read heap memory as its K, one with 1-D poses ended in std::bad_alloc: a security review)
inline Scene scene_of_bundle(const sgd::Bundle& b, const std::string& path = "the bundle") {
  Scene s;
  s.features = &need(b, path, "features", "f32", 2);
  s.nbr = &need(b, path, "nbr", "i32", 2);
  s.mask = &need(b, path, "mask", "u8", 2);
  s.descriptor = &need(b, path, "descriptor", "f32", 1);
  s.joints = &need(b, path, "joints", "f32", 2);
  if (b.has("log_wbody")) s.log_wbody = &need(b, path, "log_wbody", "f32", 2);
  const auto& rest = need(b, path, "rest", "f32", 2);
  const auto& poses = need(b, path, "poses", "f32", 2);
  const auto& trans = need(b, path, "trans", "f32", 2);
  s.N = s.M = rest.shape[0];
  s.K = s.nbr->shape[1];
  s.S = s.joints->shape[0];
  s.T = poses.shape[0];
  s.D = poses.shape[1];
  if (rest.shape[1] != 3 || s.N < 1 || s.nbr->shape[0] != s.N || s.mask->shape != s.nbr->shape ||
      s.features->shape[0] != s.N || s.joints->shape[1] != 3 || s.D != 3 * s.S || s.T < 1 ||
      trans.shape[0] != s.T || trans.shape[1] != 3 ||
      (s.log_wbody && (s.log_wbody->shape[0] != s.N || s.log_wbody->shape[1] != s.S)))
    throw std::runtime_error(path + ": fields do not agree (expected rest (N, 3), nbr and mask (N, K), features (N, F), "
                             "joints (S, 3), poses (T, 3 S), trans (T, 3), log_wbody (N, S))");
  const int32_t* nb = s.nbr->as<int32_t>();
  for (int64_t i = 0; i < s.nbr->count(); ++i)
    if (nb[i] < 0 || nb[i] >= s.N)
      throw std::runtime_error(path + ": nbr index out of range (expected 0.." + std::to_string(s.N - 1) + ", got " +
                               std::to_string(nb[i]) + ")");
  if (!b.has("betas")) throw std::runtime_error(path + ": field 'betas' is missing");
  s.rest = floats(rest);
  s.betas = floats(b.at("betas"));
  s.poses = floats(poses);
  s.trans = floats(trans);
  // a scene with frames A:B: its motion starts at A, and so does the point cache (as `segadeform run` numbers it)
  s.start_frame = b.meta.has("start_frame") ? static_cast<float>(b.meta["start_frame"].num) : 0.f;
  return s;
}

inline const sgd::Array& need(const sgd::Bundle& b, const std::string& path, const std::string& name, const std::string& dtype,
                       size_t ndim) {
  if (!b.has(name) || b.at(name).dtype != dtype || b.at(name).shape.size() != ndim)
    throw std::runtime_error(path + ": field '" + name + "' is missing or malformed (expected " + dtype + " with " +
                             std::to_string(ndim) + " dims)");
  return b.at(name);
}

// A file's meta.warnings (what the command that wrote it said): one-line texts, as Python's readers and Node's hold
// them; anything else is refused naming the file.
inline std::vector<std::string> one_line_texts(const sgd::Json& meta, const std::string& path) {
  std::vector<std::string> out;
  if (!meta.has("warnings")) return out;
  const sgd::Json& said = meta["warnings"];
  bool ok = said.kind == sgd::Json::Array;
  for (const auto& w : said.arr) {
    ok = ok && w.kind == sgd::Json::String && !w.str.empty() && w.str.find('\n') == std::string::npos;
    if (ok) out.push_back(w.str);
  }
  if (!ok)
    throw std::runtime_error(path + ": meta.warnings is not a list of one-line texts (expected strings without line "
                             "breaks)");
  return out;
}

// A schema-3 asset's garment as given and the map to it from the model's garment (garment export --resolution),
// checked as Python's GarmentAsset checks them: all five fields or none.  Sets s.N, vertices64 and faces to the garment
// as given, and model_faces to the model's (M vertices).
inline void carry_of_asset(Scene& s, const sgd::Bundle& a, const std::string& apath, int version) {
  static const char* fields[] = {"out_vertices", "out_faces", "carry_face", "carry_bary", "carry_offset"};
  int given = 0;
  for (const char* k : fields) given += a.has(k) ? 1 : 0;
  if (given == 0 && version != 3) return;
  if (given != 5)
    throw std::runtime_error(apath + ": a decimated model garment needs out_vertices, out_faces, carry_face, "
                             "carry_bary and carry_offset (expected all five)");
  const auto& ov = need(a, apath, "out_vertices", "f64", 2);
  const auto& of = need(a, apath, "out_faces", "i32", 2);
  const auto& cf = need(a, apath, "carry_face", "i32", 1);
  const auto& cb = need(a, apath, "carry_bary", "f64", 2);
  const auto& co = need(a, apath, "carry_offset", "f64", 1);
  const int64_t P = ov.shape[0], F = s.faces->shape[0];
  if (P < 1 || ov.shape[1] != 3 || cf.shape[0] != P || cb.shape[0] != P || cb.shape[1] != 3 || co.shape[0] != P ||
      of.shape[1] != 3 || of.shape[0] < 1)
    throw std::runtime_error(apath + ": the carry fields do not agree (expected out_vertices (P, 3), out_faces (G, 3), "
                             "carry_face (P), carry_bary (P, 3), carry_offset (P))");
  const int32_t* o = of.as<int32_t>();
  for (int64_t i = 0; i < of.count(); ++i)
    if (o[i] < 0 || o[i] >= P)
      throw std::runtime_error(apath + ": field 'out_faces' has an index out of range (expected 0.." +
                               std::to_string(P - 1) + ", got " + std::to_string(o[i]) + ")");
  const int32_t* c = cf.as<int32_t>();
  for (int64_t i = 0; i < P; ++i)
    if (c[i] < 0 || c[i] >= F)
      throw std::runtime_error(apath + ": field 'carry_face' has an index out of range (expected 0.." +
                               std::to_string(F - 1) + ", got " + std::to_string(c[i]) + ")");
  for (const char* k : {"out_vertices", "carry_bary", "carry_offset"}) finite_values(a.at(k), apath, k);
  const double* w = cb.as<double>();  // weights (1, 1, 0) on a face (A, A, B) put a vertex twice as far
  for (int64_t i = 0; i < P; ++i) {
    const double sum = w[3 * i] + w[3 * i + 1] + w[3 * i + 2];
    if (!(std::fabs(sum - 1.0) <= 1e-6))
      throw std::runtime_error(apath + ": field 'carry_bary' has weights that do not sum to 1 (an asset exported by a "
                               "release that put a vertex on a face with a repeated corner twice: export it again) "
                               "(expected each row summing to 1 within 1e-06, got row " + std::to_string(i) + ")");
  }
  const double* d = ov.as<double>();
  for (int64_t i = 0; i < ov.count(); ++i)
    if (std::fabs(d[i]) > 1e4)
      throw std::runtime_error(apath + ": field 'out_vertices' lies beyond 10 km (expected |x| <= 10000 m)");
  s.model_faces = s.faces;
  s.carry_face = &cf;
  s.carry_bary = &cb;
  s.carry_offset = &co;
  s.N = P;
  s.vertices64 = &ov;
  s.faces = &of;
}

// Frames of the model's garment, b * M * 3, carried to the garment as given, out (b * N * 3): each vertex at its
// barycentric place on its triangle plus its offset along the triangle's unit normal (float64 sums, as
// segadeform.body.resample.SurfaceMap.apply; the Node runtime's carryFrames).
inline void carry_frames(const Scene& s, const float* x, int64_t b, float* out) {
  const int64_t M = s.M, N = s.N;
  const int32_t* face = s.carry_face->as<int32_t>();
  const int32_t* tri = s.model_faces->as<int32_t>();
  const double* bary = s.carry_bary->as<double>();
  const double* off = s.carry_offset->as<double>();
  for (int64_t k = 0; k < b; ++k) {
    const float* xk = x + k * M * 3;
    float* ok = out + k * N * 3;
    for (int64_t i = 0; i < N; ++i) {
      const float* p0 = xk + 3 * static_cast<int64_t>(tri[3 * face[i]]);
      const float* p1 = xk + 3 * static_cast<int64_t>(tri[3 * face[i] + 1]);
      const float* p2 = xk + 3 * static_cast<int64_t>(tri[3 * face[i] + 2]);
      const double e1x = double(p1[0]) - p0[0], e1y = double(p1[1]) - p0[1], e1z = double(p1[2]) - p0[2];
      const double e2x = double(p2[0]) - p0[0], e2y = double(p2[1]) - p0[1], e2z = double(p2[2]) - p0[2];
      double nx = e1y * e2z - e1z * e2y, ny = e1z * e2x - e1x * e2z, nz = e1x * e2y - e1y * e2x;
      const double len = std::max(std::sqrt(nx * nx + ny * ny + nz * nz), 1e-300), o = off[i];
      nx /= len;  // (Python's order of operations: the same float64 numbers)
      ny /= len;
      nz /= len;
      const double w0 = bary[3 * i], w1 = bary[3 * i + 1], w2 = bary[3 * i + 2];
      ok[3 * i] = static_cast<float>(w0 * p0[0] + w1 * p1[0] + w2 * p2[0] + o * nx);
      ok[3 * i + 1] = static_cast<float>(w0 * p0[1] + w1 * p1[1] + w2 * p2[1] + o * ny);
      ok[3 * i + 2] = static_cast<float>(w0 * p0[2] + w1 * p1[2] + w2 * p2[2] + o * nz);
    }
  }
}

// The garment of a scene: a garment asset's fields, checked (`force`: an asset exported with --force is played).
inline Scene garment_of_asset(const sgd::Bundle& a, const std::string& apath, bool force) {
  if (!a.meta.has("kind") || a.meta["kind"].str != "segadeform-garment-asset")
    throw std::runtime_error(apath + ": not a garment asset (expected meta.kind 'segadeform-garment-asset')");
  const int av = static_cast<int>(a.meta["schema_version"].num);
  if (av != 1 && av != 2 && av != 3)
    throw std::runtime_error(apath + ": unsupported garment asset schema version (expected 1, 2 or 3, got " +
                             std::to_string(av) + ")");
  if (!a.has("betas") || !a.has("log_wbody") || !a.meta.has("body"))
    throw std::runtime_error(apath + ": the garment asset is not prepared for a body shape (expected a schema-2 asset "
                             "with betas, log_wbody and body: segadeform garment export GARMENT --betas ... -o G.sgda)");
  const auto& v = need(a, apath, "vertices", "f64", 2);
  Scene s;
  s.features = &need(a, apath, "features", "f32", 2);
  s.nbr = &need(a, apath, "nbr", "i32", 2);
  s.mask = &need(a, apath, "mask", "u8", 2);
  s.descriptor = &need(a, apath, "descriptor", "f64", 1);
  s.joints = &need(a, apath, "joints", "f64", 2);
  s.log_wbody = &need(a, apath, "log_wbody", "f32", 2);
  s.N = v.shape[0];
  s.K = s.nbr->shape[1];
  s.S = s.joints->shape[0];
  if (s.nbr->shape[0] != s.N || s.mask->shape != s.nbr->shape || s.features->shape[0] != s.N ||
      s.features->shape[1] != 6 + s.S || s.log_wbody->shape[0] != s.N || s.log_wbody->shape[1] != s.S)
    throw std::runtime_error(apath + ": fields do not agree (expected nbr, mask (N, K), features (N, 6 + S), log_wbody (N, S))");
  const int32_t* nb = s.nbr->as<int32_t>();
  for (int64_t i = 0; i < s.nbr->count(); ++i)
    if (nb[i] < 0 || nb[i] >= s.N)
      throw std::runtime_error(apath + ": nbr index out of range (expected 0.." + std::to_string(s.N - 1) + ", got " +
                               std::to_string(nb[i]) + ")");
  const auto& faces = need(a, apath, "faces", "i32", 2);
  {
    const int32_t* fa = faces.as<int32_t>();
    if (faces.shape[1] != 3 || faces.shape[0] < 1)
      throw std::runtime_error(apath + ": field 'faces' has the wrong shape (expected (F, 3), F >= 1)");
    for (int64_t i = 0; i < faces.count(); ++i)
      if (fa[i] < 0 || fa[i] >= s.N)
        throw std::runtime_error(apath + ": face index out of range (expected 0.." + std::to_string(s.N - 1) +
                                 ", got " + std::to_string(fa[i]) + ")");
  }
  // values, as the Python runtime checks them (NaN or inf here gave a cache of NaN with exit 0: a user's trial)
  for (const char* k : {"vertices", "normals", "features", "joints", "descriptor", "betas", "log_wbody"})
    if (a.has(k)) finite_values(a.at(k), apath, k);
  for (const char* k : {"vertices", "joints"}) {  // positions within 10 km, as Python's GarmentAsset holds them
    const double* d = a.at(k).as<double>();
    for (int64_t i = 0; i < a.at(k).count(); ++i)
      if (std::fabs(d[i]) > 1e4)
        throw std::runtime_error(apath + ": field '" + k + "' lies beyond 10 km (expected |x| <= 10000 m)");
  }
  s.rest = floats(v);
  s.betas = floats(a.at("betas"));
  s.D = 3 * s.S;
  s.body_sha = a.meta["body"]["sha256"].str;
  s.weight_prior = a.meta["body"].has("weight_prior") ? a.meta["body"]["weight_prior"].str : "nearest";
  s.vertices64 = &v;
  s.faces = &faces;
  s.M = s.N;
  carry_of_asset(s, a, apath, av);
  // what `segadeform garment export` said of the garment (a mesh split at its seams tears ...), said again here
  for (const std::string& w : one_line_texts(a.meta, apath))
    s.warnings.push_back("when the garment asset was exported: " + w);
  // an asset exported with --force for a body it does not sit on: refused unless forced again, as `segadeform run`
  // refuses it (it checks the fit itself)
  if (a.meta["body"].has("unfit") && a.meta["body"]["unfit"].kind == sgd::Json::String) {
    const std::string why = "the garment asset was exported with --force although " + a.meta["body"]["unfit"].str;
    if (!force)
      throw std::runtime_error(apath + ": " + why + " (expected a garment that sits on its body, or --force here too)");
    s.warnings.push_back(why);
  }
  return s;
}

// A motion file's poses, translations, frame rate and first frame into the garment's scene `s`, checked against it
// (`force`: a motion retargeted onto another body or shape than the asset's is played, with a warning).
inline void motion_into(Scene& s, const sgd::Bundle& m, const std::string& mpath, bool force) {
  if (!m.meta.has("kind") || m.meta["kind"].str != "segadeform-motion")
    throw std::runtime_error(mpath + ": not a motion file (expected meta.kind 'segadeform-motion')");
  if (static_cast<int>(m.meta["schema_version"].num) != 1)
    throw std::runtime_error(mpath + ": unsupported motion file schema version (expected 1)");
  const auto& poses = need(m, mpath, "poses", "f32", 3);
  const auto& trans = need(m, mpath, "trans", "f32", 2);
  finite_values(poses, mpath, "poses");
  finite_values(trans, mpath, "trans");
  {
    const float* t = trans.as<float>();
    for (int64_t i = 0; i < trans.count(); ++i)
      if (std::fabs(t[i]) > 1e4f)
        throw std::runtime_error(mpath + ": field 'trans' is beyond 10 km (expected |translation| <= 10000 m, got " +
                                 sgd::shortest(t[i]) + ")");
  }
  if (!m.meta.has("fps") || !(m.meta["fps"].num >= 1 && m.meta["fps"].num <= 1000))
    throw std::runtime_error(mpath + ": meta.fps must be a frame rate (expected 1..1000)");
  if (m.meta.has("start_frame")) {
    const double sf = m.meta["start_frame"].num;
    if (!(std::isfinite(sf) && sf == std::floor(sf) && std::fabs(sf) <= 2147483647.0))
      throw std::runtime_error(mpath + ": meta.start_frame must be a frame number (expected an integer of 32 bits)");
  }
  if (m.meta.has("betas"))
    for (const auto& b : m.meta["betas"].arr)
      if (!std::isfinite(b.num)) throw std::runtime_error(mpath + ": meta.betas contains NaN or inf");
  // what `segadeform motion export` said of the motion (capture glitches ...), said again here
  for (const std::string& w : one_line_texts(m.meta, mpath)) s.warnings.push_back("when the motion file was exported: " + w);
  if (poses.shape[1] != s.S || poses.shape[2] != 3 || trans.shape[0] != poses.shape[0] || trans.shape[1] != 3 ||
      poses.shape[0] < 1)
    throw std::runtime_error(mpath + ": poses and trans do not fit the garment asset (expected (T, " +
                             std::to_string(s.S) + ", 3) and (T, 3))");
  s.poses = floats(poses);
  canonical_axis_angle(s.poses);  // every rotation written one way, as Python's motions hold them
  s.trans = floats(trans);
  s.T = poses.shape[0];
  s.fps = m.meta["fps"].num;
  s.start_frame = m.meta.has("start_frame") ? static_cast<float>(m.meta["start_frame"].num) : 0.f;
  // a motion made for another body or shape is refused, as `segadeform run` refuses it; --force plays it, warned
  const auto mismatch = [&](const std::string& what) {
    const std::string msg = "the motion was retargeted onto another " + what + " than the garment asset's";
    if (!force)
      throw std::runtime_error(mpath + ": " + msg + " (expected a motion exported for the asset's body and --betas: " +
                               "segadeform motion export ... --betas ..., or --force)");
    s.warnings.push_back(msg);
  };
  if (m.meta.has("body") && m.meta["body"]["sha256"].str != s.body_sha) mismatch("body");
  if (m.meta.has("betas")) {
    const std::vector<sgd::Json>& mb = m.meta["betas"].arr;
    for (size_t i = 0; i < mb.size(); ++i) {
      const double ab = i < s.betas.size() ? static_cast<double>(s.betas[i]) : 0.0;
      if (std::fabs(mb[i].num - ab) > 1e-6) {
        mismatch("body shape (betas)");
        break;
      }
    }
  }
}

// The model's betas: the scene's, zero-padded or cut to `nb` (a cut coefficient must be 0).
inline std::vector<float> model_betas(const std::vector<float>& betas, int64_t nb) {
  std::vector<float> out(static_cast<size_t>(nb), 0.f);
  for (size_t i = 0; i < betas.size(); ++i) {
    if (static_cast<int64_t>(i) < nb) out[i] = betas[i];
    else if (betas[i] != 0.f)
      throw std::runtime_error("too many shape coefficients for this model (expected <= " + std::to_string(nb) + ")");
  }
  return out;
}


// A package whose body graph poses another body than its model was trained on (manifest.training_body;
// `segadeform export-body --force` gives it one) is refused unless `force`, as `segadeform run` refuses it; forced,
// `warnings` says so.
// `hint`: what forces it where the caller is (the bundle form of segadeform-run cannot).
inline void check_training_body(const Package& pkg, bool force, std::vector<std::string>& warnings,
                                const std::string& hint = "--force") {
  const sgd::Json& m = pkg.manifest;
  if (!m.has("training_body") || !m["training_body"].has("sha256") || m["training_body"]["sha256"].str.empty()) return;
  const sgd::Json& want = m["training_body"];
  static const sgd::Json none;
  for (const auto& kv : (m.has("graphs") ? m["graphs"] : none).obj) {
    const sgd::Json& g = kv.second;
    // a graph that records no body is not checked (the Python runtime poses with numpy there)
    if (!g.has("role") || g["role"].str != "body" || !g.has("body") || !g["body"].has("sha256") ||
        g["body"]["sha256"].str.empty() || g["body"]["sha256"].str == want["sha256"].str)
      continue;
    const std::string got_name = g["body"].has("name") ? g["body"]["name"].str : std::string("a body");
    const std::string want_name = want.has("name") ? want["name"].str : std::string("a body");
    const std::string why = "the package's body graph '" + kv.first + "' poses another body than its model was " +
                            "trained on (expected " + want_name + " " + want["sha256"].str.substr(0, 12) + ", got " +
                            got_name + " " + g["body"]["sha256"].str.substr(0, 12) + ")";
    if (!force)
      throw std::runtime_error(pkg.dir + ": " + why + ": the model never saw this body (segadeform export-body " +
                               "without --force gives the package its training body back; or " + hint + ")");
    warnings.push_back(why);
    return;
  }
}

// A garment asset and a motion file: the scene segadeform-run plays.
inline Scene scene_of_asset(const sgd::Bundle& a, const std::string& apath, const sgd::Bundle& m, const std::string& mpath,
                            bool force) {
  Scene s = garment_of_asset(a, apath, force);
  motion_into(s, m, mpath, force);
  return s;
}

// Frames computed at the root moved to the translation, in place: B frames of K points (B * K * 3) and trans (B * 3),
// each coordinate the float64 sum rounded to float32.  Every graph runs at the root (trans zero) so that its float32
// numbers are the same wherever the character stands (100 m from the origin a deep vertex left the body on the other
// side: a garment 5.9 cm off); Python's segadeform.runtime.translation and Node's atTranslation do the same.
inline void at_translation(float* frames, const float* trans, int64_t B, int64_t K) {
  for (int64_t b = 0; b < B; ++b)
    for (int64_t k = 0; k < K; ++k)
      for (int c = 0; c < 3; ++c) {
        float& x = frames[(b * K + k) * 3 + c];
        x = static_cast<float>(static_cast<double>(x) + static_cast<double>(trans[3 * b + c]));
      }
}

// The package's body graph (betas (|beta|,), poses (B, S, 3), trans (B, 3) -> vertices, ...), run a batch of frames at
// a time: pose(poses, trans, B) gives B frames (B * V * 3), so that a long clip never holds its posed body whole
// (21,000 frames of the default body held 3.5 GB); faces() its triangles (the graph's constant `faces` output),
// rest() the body at zero pose and no translation.
class BodyPoser {
 public:
  BodyPoser(OrtEnv* env, const Package& pkg, const sgd::Json& spec, const Scene& sc, int threads)
      : sess_(env, pkg.graph_file(spec), threads) {
    if (spec.has("body") && !sc.body_sha.empty() && spec["body"]["sha256"].str != sc.body_sha)
      throw std::runtime_error("the garment asset was prepared for another body than the package's (" +
                               spec["body"]["name"].str + ")");
    nb_ = static_cast<int64_t>(spec["inputs"].arr[0]["shape"].arr[0].num);
    s_ = static_cast<int64_t>(spec["inputs"].arr[1]["shape"].arr[1].num);
    v_ = static_cast<int64_t>(spec["outputs"].arr[0]["shape"].arr[1].num);
    if (s_ != sc.S) throw std::runtime_error("the body graph poses " + std::to_string(s_) + " joints, the motion has " +
                                             std::to_string(sc.S));
    betas_ = model_betas(sc.betas, nb_);
  }
  int64_t V() const { return v_; }
  std::vector<float> pose(const float* poses, const float* trans, int64_t B) {  // run at the root, then moved
    std::vector<float> v = run(std::vector<float>(poses, poses + B * s_ * 3), std::vector<float>(B * 3, 0.f), B);
    at_translation(v.data(), trans, B, v_);
    return v;
  }
  std::vector<float> rest() { return run(std::vector<float>(static_cast<size_t>(3 * s_), 0.f), {0.f, 0.f, 0.f}, 1); }
  const std::vector<int32_t>& faces() {
    if (faces_.empty()) rest();
    return faces_;
  }

 private:
  std::vector<float> run(std::vector<float> poses, std::vector<float> trans, int64_t B) {
    std::vector<Input> in;
    in.push_back(input_floats("betas", betas_, {nb_}));
    in.push_back(input_floats("poses", std::move(poses), {B, s_, 3}));
    in.push_back(input_floats("trans", std::move(trans), {B, 3}));
    std::vector<Output> o = sess_.run(in, faces_.empty() ? std::vector<std::string>{"vertices", "faces"}
                                                         : std::vector<std::string>{"vertices"});
    release(in);
    if (faces_.empty()) faces_ = std::move(o[1].i);
    return std::move(o[0].f);
  }
  Session sess_;
  int64_t nb_ = 0, s_ = 0, v_ = 0;
  std::vector<float> betas_;
  std::vector<int32_t> faces_;
};

// What a Stream runs and how: the effects, the cloth stage's knobs, the collision margin, the motion's frame rate
// (the cloth stage's time step), frames per onnxruntime call, threads, and whether the posed body is wanted.
struct StreamOptions {
  Effects effects;
  ClothSettings cloth;
  double margin = DEFAULT_COLLISION_MARGIN;
  double fps = 0;
  int batch = 8, threads = 1;
  bool body = false;
};

// A motion played a chunk at a time: the garment encoded once; push(poses, trans, B, frames, body) runs the
// deformer on the next B frames in batches of `batch` -- the motion window reaching back into earlier chunks (before
// the first frame: the first frame) -- then, a batch at a time, poses the body and runs the cloth stage or collisions,
// whose state (the stage's velocities, its collider) is carried from chunk to chunk.  Chunks that are multiples of
// `batch` give the frames of one push of the whole motion bit for bit (the same onnxruntime batches); others run
// other batch sizes (1e-6 m), which a push-out in a crease can make millimetres.  reset() starts a new clip.
class Stream {
 public:
  // `sc`: the garment's fields (features, nbr, mask, descriptor, joints, log_wbody, rest, betas; vertices64 and faces
  // for the cloth stage), kept by reference: it must outlive the stream.
  Stream(OrtEnv* env, const Package& pkg, const Scene& sc, const StreamOptions& opt) : sc_(sc), opt_(opt) {
    if (opt_.effects.cloth) opt_.effects.collisions = false;  // the stage's contact replaces the push-out
    if (opt.batch < 1) throw std::runtime_error("batch must be an integer >= 1 (got " + std::to_string(opt.batch) + ")");
    if (opt.threads < 1)
      throw std::runtime_error("threads must be an integer >= 1 (got " + std::to_string(opt.threads) + ")");
    opt_.batch = effective_batch(opt.batch, sc.M);
    if (!(opt.margin >= 0 && opt.margin < 1))
      throw std::runtime_error("the collision margin must be in [0, 1) metres (got " + sgd::shortest(opt.margin) + ")");
    const Effects& eff = opt_.effects;
    if (eff.cloth && !sc.vertices64)
      throw std::runtime_error("the cloth stage needs a garment asset and a motion file (expected .sgda and .sgdm, got a "
                               "scene bundle)");
    if (eff.cloth && !(opt.fps > 0)) throw std::runtime_error("the motion file's fps must be positive");
    // an asset prepared for another body than the package's is refused whatever the effects (only the body graph's
    // poser checked it, so `none` played it), as `segadeform run` refuses it
    static const sgd::Json none;
    for (const auto& kv : (pkg.manifest.has("graphs") ? pkg.manifest["graphs"] : none).obj) {
      const sgd::Json& g = kv.second;
      if (g.has("role") && g["role"].str == "body" && g.has("body") && !sc.body_sha.empty() &&
          g["body"]["sha256"].str != sc.body_sha)
        throw std::runtime_error("the garment asset was prepared for another body than the package's (expected " +
                                 g["body"]["name"].str + " " + g["body"]["sha256"].str.substr(0, 12) + ", got " +
                                 sc.body_sha.substr(0, 12) + ")");
    }
    const sgd::Json& dec_spec = pkg.deformer(eff);
    const bool need_body = opt.body || eff.collisions || eff.cloth;
    const sgd::Json* body_spec = need_body ? pkg.body(eff.skinning) : nullptr;
    if (need_body && !body_spec)
      throw std::runtime_error(std::string(eff.cloth ? "the cloth stage needs the posed body, and "
                                           : eff.collisions ? "collisions need the posed body, and " : "") +
                               "the package has no body graph (segadeform export-body [BODY] -o PACKAGE adds one)");
    try {  // the deformer's fixed inputs are released if anything after them fails (the destructor does not run)
      open_deformer(env, pkg, dec_spec);
      if (body_spec) {
        poser_.reset(new BodyPoser(env, pkg, *body_spec, sc, opt.threads));
        if (eff.cloth || eff.collisions) {  // the stage's rest, and the body the collider's tree is built from
          const auto t1 = Clock::now();
          rest_body_ = poser_->rest();
          ms_stage_ += since(t1);
        }
      }
      reset();
    } catch (...) {
      release(fixed_);
      throw;
    }
  }
  ~Stream() { release(fixed_); }
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;

  // A new clip: no motion history; the cloth stage starts again from the network's frame, the collider anew.
  void reset() {
    broken_ = false;
    prev_.clear();
    seen_ = 0;
    collider_.reset();
    stage_.reset();
    if (opt_.effects.cloth) {
      const auto t0 = Clock::now();
      const std::vector<int32_t>& bf = poser_->faces();
      stage_.reset(new sgd::Cloth(sc_.vertices64->as<double>(), sc_.N, sc_.faces->as<int32_t>(), sc_.faces->shape[0],
                                  rest_body_.data(), poser_->V(), bf.data(), static_cast<int64_t>(bf.size() / 3),
                                  opt_.cloth, opt_.margin, 1.0 / opt_.fps));
      ms_stage_ += since(t0);
    }
  }

  // The next B frames: poses (B * D, axis-angle in [0, pi] as canonical_axis_angle writes them), trans (B * 3) ->
  // frames (B * N * 3) and, when `body` is not null, the posed body (B * V * 3).
  void push(const float* poses, const float* trans, int64_t B, float* frames, float* body) {
    const int64_t N = sc_.N, D = sc_.D, V = this->V();
    if (B < 1) throw std::runtime_error("push: expected at least one frame (got " + std::to_string(B) + ")");
    if (broken_)
      throw std::runtime_error("push: an earlier push failed part-way, leaving the stages' state behind the motion "
                               "(expected reset() first)");
    broken_ = true;  // until this push ends: a batch that throws leaves the cloth stage ahead of the history
    // the motion the windows read: the poses kept from earlier chunks, then this one (frame `first` at index 0)
    const int64_t hist = static_cast<int64_t>(prev_.size()) / D, first = seen_ - hist;
    std::vector<float> all(prev_);
    all.insert(all.end(), poses, poses + B * D);
    // the deformer over the chunk's batches, then the body and the stages over the same batches (one graph at a time
    // runs faster than the two in alternation: 15-20 % of segadeform-run's CPU time, measured)
    // the graphs run at the root (at_translation); collisions are resolved there, the cloth stage steps at the
    // translation in float64, and the translation is added last
    const std::vector<float> zero(static_cast<size_t>(opt_.batch * 3), 0.f);
    for (int64_t lo = 0; lo < B; lo += opt_.batch) {
      const int64_t hi = std::min<int64_t>(lo + opt_.batch, B), b = hi - lo;
      const auto t0 = Clock::now();
      deform(all, first, seen_ + lo, b, zero.data(), frames + lo * N * 3);
      ms_deform_ += since(t0);
      if (!poser_) at_translation(frames + lo * N * 3, trans + lo * 3, b, N);
    }
    for (int64_t lo = 0; poser_ && lo < B; lo += opt_.batch) {
      const int64_t hi = std::min<int64_t>(lo + opt_.batch, B), b = hi - lo;
      auto t0 = Clock::now();
      const std::vector<float> posed = poser_->pose(poses + lo * D, zero.data(), b);
      ms_body_ += since(t0);
      if (body) {
        std::copy(posed.begin(), posed.end(), body + lo * V * 3);
        at_translation(body + lo * V * 3, trans + lo * 3, b, V);
      }
      t0 = Clock::now();
      if (stage_) {
        stage_->step(frames + lo * N * 3, b, posed.data(), trans + lo * 3);
        ms_stage_ += since(t0);
        continue;
      }
      if (opt_.effects.collisions) {
        const std::vector<int32_t>& bf = poser_->faces();
        if (!collider_)  // from the body at rest, as segadeform run builds it (the tree decides between equally
          // near triangles: built from the clip's first pose, a frame moved 2 cm where Python's did not)
          collider_.reset(new sgd::Collider(rest_body_.data(), V, bf.data(), static_cast<int64_t>(bf.size() / 3)));
        moved_ += collider_->push_out(frames + lo * N * 3, b, N, posed.data(), opt_.margin, opt_.threads);
      }
      at_translation(frames + lo * N * 3, trans + lo * 3, b, N);
      if (opt_.effects.collisions) ms_stage_ += since(t0);
    }
    seen_ += B;
    frames_ += B;
    const int64_t keep = std::min<int64_t>(window_ - 1, hist + B);
    prev_.assign(all.end() - keep * D, all.end());
    broken_ = false;
  }

  int64_t V() const { return poser_ ? poser_->V() : 0; }
  // the body at zero pose and no translation (the rest mesh a body PC2 animates)
  std::vector<float> rest_body() {
    if (!poser_) throw std::runtime_error("the stream poses no body");
    return poser_->rest();
  }
  const std::vector<int32_t>& body_faces() {
    if (!poser_) throw std::runtime_error("the stream poses no body");
    return poser_->faces();
  }
  const sgd::Cloth* cloth() const { return stage_.get(); }
  int64_t moved() const { return moved_; }  // vertex-frames pushed out by collisions (no cloth stage)
  int batch() const { return opt_.batch; }  // frames per deformer call (lowered for a big garment: effective_batch)
  int64_t frames() const { return frames_; }  // frames pushed since the stream opened (resets included)
  const Effects& effects() const { return opt_.effects; }
  // milliseconds spent since the stream opened: the encoder and deformer, the body graph, the cloth stage or
  // collisions (their setup included)
  double ms_deform() const { return ms_deform_; }
  double ms_body() const { return ms_body_; }
  double ms_stage() const { return ms_stage_; }

 private:
  using Clock = std::chrono::steady_clock;
  static double since(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  }

  // the encoder once; the deformer's session and fixed inputs (sessions from the file path: the graphs may keep
  // their weights in the package's shared weights.bin)
  void open_deformer(OrtEnv* env, const Package& pkg, const sgd::Json& dec_spec) {
    const sgd::Json& enc_spec = pkg.manifest["graphs"]["garment_encoder"];
    const Scene& sc = sc_;
    Session enc(env, pkg.graph_file(enc_spec), opt_.threads, /*arena=*/false);
    dec_.reset(new Session(env, pkg.graph_file(dec_spec), opt_.threads));
    const auto t0 = Clock::now();  // the encoder's run and the deformer's (not the sessions' creation)
    const int64_t N = sc.M, K = sc.K, S = sc.S;  // the model's garment
    window_ = static_cast<int64_t>(find_input(dec_spec, "window")["shape"].arr[1].num);
    nb_ = static_cast<int64_t>(find_input(dec_spec, "betas")["shape"].arr[1].num);
    betas_ = model_betas(sc.betas, nb_);
    joints_ = floats(*sc.joints);
    out_name_ = dec_spec["outputs"].arr[0]["name"].str;
    // the encoder's inputs, fed by name (older encoders also take betas)
    std::vector<Input> ein;
    for (const auto& i : enc_spec["inputs"].arr) {
      const std::string& name = i["name"].str;
      if (name == "features") ein.push_back(input_from(enc_spec, name, *sc.features, {1, N, sc.features->shape[1]}));
      else if (name == "nbr") ein.push_back(input_from(enc_spec, name, *sc.nbr, {N, K}));
      else if (name == "mask") ein.push_back(input_from(enc_spec, name, *sc.mask, {N, K}));
      else if (name == "descriptor") {
        const sgd::Json& shape = i["shape"];
        const int64_t want = shape.arr.size() == 2 ? static_cast<int64_t>(shape.arr[1].num) : -1;
        if (want > 0 && want != sc.descriptor->shape[0]) {  // (onnxruntime's own error named neither)
          release(ein);
          throw std::runtime_error("the garment asset was exported for another model; export it for this one: "
                                   "segadeform garment export GARMENT --model PACKAGE (expected a garment descriptor "
                                   "of " + std::to_string(want) + " values, got " +
                                   std::to_string(sc.descriptor->shape[0]) + ")");
        }
        ein.push_back(input_from(enc_spec, name, *sc.descriptor, {1, sc.descriptor->shape[0]}));
      }
      else if (name == "betas") ein.push_back(input_floats(name, betas_, {1, nb_}));
      else {
        release(ein);
        throw std::runtime_error("the garment encoder takes '" + name + "', which this runtime cannot feed");
      }
    }
    // its one output, without the batch axis, is the deformer input of the same name (g (N, K S) for K networks;
    // older: P (N, S, F))
    const std::string code_name = enc_spec["outputs"].arr[0]["name"].str;
    Output code;
    try {
      code = std::move(enc.run(ein, {code_name})[0]);
    } catch (...) {
      release(ein);
      throw;
    }
    release(ein);
    fixed_.push_back(input_floats(code_name, code.f, std::vector<int64_t>(code.shape.begin() + 1, code.shape.end())));
    fixed_.push_back(input_floats("rest", sc.rest, {N, 3}));
    fixed_.push_back(input_from(dec_spec, "nbr", *sc.nbr, {N, K}));
    fixed_.push_back(input_from(dec_spec, "mask", *sc.mask, {N, K}));
    if (has_input(dec_spec, "log_wbody")) {
      if (!sc.log_wbody) throw std::runtime_error("this model needs the body's weights at the garment (log_wbody)");
      const sgd::Json& cfg = pkg.manifest["config"];
      const std::string want = cfg.has("weight_prior") ? cfg["weight_prior"].str : "nearest";
      if (!sc.weight_prior.empty() && sc.weight_prior != want)
        throw std::runtime_error("the garment asset's log_wbody was made with the " + sc.weight_prior +
                                 " weight prior, the model wants " + want +
                                 " (expected an asset from segadeform garment export --model PACKAGE)");
      fixed_.push_back(input_from(dec_spec, "log_wbody", *sc.log_wbody, {N, S}));
    }
    ms_deform_ += since(t0);
  }

  // b frames from global frame g0 into out (b * N * 3; the model's b * M * 3 carried to them): the window of frame t is t, t-1, ... t-window+1 (before the
  // clip's first frame: that frame), read from `all` (global frame `first` at index 0)
  void deform(const std::vector<float>& all, int64_t first, int64_t g0, int64_t b, const float* trans, float* out) {
    const int64_t D = sc_.D, S = sc_.S, W = window_;
    std::vector<float> win(static_cast<size_t>(b * W * D)), bb(static_cast<size_t>(b * nb_)),
        jj(static_cast<size_t>(b * S * 3)), tt(trans, trans + b * 3);  // at the root: push() passes zeros
    for (int64_t i = 0; i < b; ++i) {
      for (int64_t k = 0; k < W; ++k) {
        const int64_t src = std::max<int64_t>(g0 + i - k, 0) - first;
        std::copy(all.begin() + src * D, all.begin() + src * D + D, win.begin() + (i * W + k) * D);
      }
      std::copy(betas_.begin(), betas_.end(), bb.begin() + i * nb_);
      std::copy(joints_.begin(), joints_.end(), jj.begin() + i * S * 3);
    }
    std::vector<Input> din;
    din.push_back(input_floats("window", win, {b, W, D}));
    din.push_back(input_floats("betas", bb, {b, nb_}));
    din.push_back(input_floats("joints", jj, {b, S, 3}));
    din.push_back(input_floats("trans", tt, {b, 3}));
    std::vector<Input> in;
    for (auto& f : fixed_) in.push_back(Input{f.name, {}, f.dims, f.value});
    for (auto& d : din) in.push_back(Input{d.name, {}, d.dims, d.value});
    try {
      Output v = std::move(dec_->run(in, {out_name_})[0]);
      if (sc_.carry_face) carry_frames(sc_, v.f.data(), b, out);  // the model's garment carried to the one given
      else std::copy(v.f.begin(), v.f.end(), out);
    } catch (...) {
      release(din);
      throw;
    }
    release(din);
  }

  const Scene& sc_;
  StreamOptions opt_;
  std::unique_ptr<Session> dec_;
  std::vector<Input> fixed_;
  std::vector<float> betas_, joints_, rest_body_, prev_;
  std::string out_name_;
  int64_t window_ = 1, nb_ = 0, seen_ = 0, frames_ = 0, moved_ = 0;
  bool broken_ = false;  // a push threw part-way: refused until reset()
  std::unique_ptr<BodyPoser> poser_;
  std::unique_ptr<sgd::Cloth> stage_;
  std::unique_ptr<sgd::Collider> collider_;
  double ms_deform_ = 0, ms_body_ = 0, ms_stage_ = 0;
};

}  // namespace engine
}  // namespace sgd

// segadeform-run: a model package and a scene bundle in, a PC2 point cache out (the C++ runtime).
//
//   segadeform-run PACKAGE_DIR BUNDLE.sgdb -o OUT.pc2 [--batch N] [--threads N] [--check]
//
// Built on the onnxruntime C API (the shared library, C++17, no other dependency).  --check compares
// the frames with the bundle's `expected` array (the Python runtime's output) and prints the error.
#include <onnxruntime_c_api.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "bundle.hpp"
#include "json.hpp"

namespace {

const OrtApi* api = nullptr;

void check(OrtStatus* s) {
  if (s) {
    std::string msg = api->GetErrorMessage(s);
    api->ReleaseStatus(s);
    throw std::runtime_error("onnxruntime: " + msg);
  }
}

std::string read_text(const std::string& path) {
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

ONNXTensorElementDataType ort_type(const std::string& dtype) {
  if (dtype == "float32") return ONNX_TENSOR_ELEMENT_DATA_TYPE_FLOAT;
  if (dtype == "int64") return ONNX_TENSOR_ELEMENT_DATA_TYPE_INT64;
  if (dtype == "int32") return ONNX_TENSOR_ELEMENT_DATA_TYPE_INT32;
  if (dtype == "bool") return ONNX_TENSOR_ELEMENT_DATA_TYPE_BOOL;
  throw std::runtime_error("unsupported input dtype " + dtype);
}

size_t elem_size(const std::string& dtype) {
  if (dtype == "int64") return 8;
  if (dtype == "bool") return 1;
  return 4;
}

// Converts a bundle array (f32, i32 or u8) to the dtype the graph input wants.
std::vector<uint8_t> convert(const sgd::Array& a, const std::string& dtype) {
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

class Session {
 public:
  Session(OrtEnv* env, const std::string& path, int threads) {
    OrtSessionOptions* so;
    check(api->CreateSessionOptions(&so));
    check(api->SetIntraOpNumThreads(so, threads));
    check(api->SetInterOpNumThreads(so, 1));
    check(api->CreateSession(env, path.c_str(), so, &s_));
    api->ReleaseSessionOptions(so);
  }
  ~Session() { if (s_) api->ReleaseSession(s_); }
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  // Runs with named inputs; returns the first output as floats and its shape.
  std::vector<float> run(std::vector<Input>& ins, const std::string& out_name, std::vector<int64_t>* shape) {
    std::vector<const char*> names;
    std::vector<OrtValue*> values;
    for (auto& in : ins) {
      if (!in.value) throw std::runtime_error("input '" + in.name + "' has no value");
      names.push_back(in.name.c_str());
      values.push_back(in.value);
    }
    const char* on = out_name.c_str();
    OrtValue* out = nullptr;
    check(api->Run(s_, nullptr, names.data(), values.data(), values.size(), &on, 1, &out));
    OrtTensorTypeAndShapeInfo* info;
    check(api->GetTensorTypeAndShape(out, &info));
    size_t nd;
    check(api->GetDimensionsCount(info, &nd));
    shape->resize(nd);
    check(api->GetDimensions(info, shape->data(), nd));
    size_t count;
    check(api->GetTensorShapeElementCount(info, &count));
    api->ReleaseTensorTypeAndShapeInfo(info);
    float* p;
    check(api->GetTensorMutableData(out, reinterpret_cast<void**>(&p)));
    std::vector<float> r(p, p + count);
    api->ReleaseValue(out);
    return r;
  }
  OrtSession* s_ = nullptr;
};

// Inputs get their element type at creation: a small helper making the OrtValue eagerly.
void make_value(Input& in, const std::string& dtype) {
  OrtMemoryInfo* mem;
  check(api->CreateCpuMemoryInfo(OrtArenaAllocator, OrtMemTypeDefault, &mem));
  check(api->CreateTensorWithDataAsOrtValue(mem, in.data.data(), in.data.size(), in.dims.data(), in.dims.size(),
                                            ort_type(dtype), &in.value));
  api->ReleaseMemoryInfo(mem);
}

void release(std::vector<Input>& ins) {
  for (auto& in : ins) if (in.value) { api->ReleaseValue(in.value); in.value = nullptr; }
}

const sgd::Json& find_input(const sgd::Json& spec, const std::string& name) {
  for (const auto& i : spec["inputs"].arr) if (i["name"].str == name) return i;
  throw std::runtime_error("graph has no input '" + name + "'");
}

Input input_from(const sgd::Json& spec, const std::string& name, const sgd::Array& a, std::vector<int64_t> dims) {
  const std::string dtype = find_input(spec, name)["dtype"].str;
  Input in{name, convert(a, dtype), std::move(dims)};
  make_value(in, dtype);
  return in;
}

Input input_floats(const std::string& name, std::vector<float> v, std::vector<int64_t> dims) {
  Input in{name, std::vector<uint8_t>(v.size() * 4), std::move(dims)};
  std::memcpy(in.data.data(), v.data(), in.data.size());
  make_value(in, "float32");
  return in;
}

void write_pc2(const std::string& path, const std::vector<float>& frames, int32_t T, int32_t N) {
  std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary);
    if (!f) throw std::runtime_error(path + ": cannot write");
    f.write("POINTCACHE2\0", 12);
    int32_t version = 1;
    float start = 0.f, rate = 1.f;
    f.write(reinterpret_cast<const char*>(&version), 4);
    f.write(reinterpret_cast<const char*>(&N), 4);
    f.write(reinterpret_cast<const char*>(&start), 4);
    f.write(reinterpret_cast<const char*>(&rate), 4);
    f.write(reinterpret_cast<const char*>(&T), 4);
    f.write(reinterpret_cast<const char*>(frames.data()), static_cast<std::streamsize>(frames.size() * 4));
    if (!f) throw std::runtime_error(path + ": write failed");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) throw std::runtime_error(path + ": cannot rename");
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  std::string out;
  int batch = 8, threads = 1;
  bool do_check = false;
  std::vector<std::string> pos;
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "-o" && i + 1 < args.size()) out = args[++i];
    else if (args[i] == "--batch" && i + 1 < args.size()) batch = std::stoi(args[++i]);
    else if (args[i] == "--threads" && i + 1 < args.size()) threads = std::stoi(args[++i]);
    else if (args[i] == "--check") do_check = true;
    else pos.push_back(args[i]);
  }
  if (pos.size() != 2 || out.empty() || batch < 1 || threads < 1) {
    std::cerr << "usage: segadeform-run PACKAGE_DIR BUNDLE.sgdb -o OUT.pc2 [--batch N] [--threads N] [--check]\n";
    return 2;
  }
  try {
    api = OrtGetApiBase()->GetApi(ORT_API_VERSION);
    if (!api) throw std::runtime_error("the onnxruntime library is older than the headers (API " +
                                       std::to_string(ORT_API_VERSION) + ")");
    const std::string dir = pos[0];
    sgd::Json manifest = sgd::parse_json(read_text(dir + "/manifest.json"));
    if (!manifest.has("format") || manifest["format"].str != "segadeform-model-package")
      throw std::runtime_error(dir + ": not a segadeform model package");
    // docs/package.md: schema 2 lists every graph once in "graphs" (deformers with role "deformer" and
    // their effects); schema 1 listed the deformers in "variants"
    const int schema = static_cast<int>(manifest["schema_version"].num);
    if (schema != 1 && schema != 2)
      throw std::runtime_error(dir + "/manifest.json: unsupported manifest schema version (expected 1 or 2, got " +
                               std::to_string(schema) + ")");
    sgd::Bundle b = sgd::read_bundle(pos[1]);
    const sgd::Json& eff = b.meta["effects"];
    const sgd::Json* dec_spec = nullptr;
    for (const auto& kv : (schema == 1 ? manifest["variants"] : manifest["graphs"]).obj) {
      if (schema == 2 && (!kv.second.has("role") || kv.second["role"].str != "deformer")) continue;
      const auto& e = kv.second["effects"];
      if (e["skinning"].str == eff["skinning"].str && e["wrinkles"].b == eff["wrinkles"].b &&
          e["dynamics"].b == eff["dynamics"].b) dec_spec = &kv.second;
    }
    if (!dec_spec) throw std::runtime_error("the package has no deformer graph for the bundle's effects");
    const sgd::Json& enc_spec = manifest["graphs"]["garment_encoder"];
    OrtEnv* env;
    check(api->CreateEnv(ORT_LOGGING_LEVEL_WARNING, "segadeform", &env));
    // sessions from the file path: the graphs may keep their weights in the package's shared weights.bin
    Session enc(env, dir + "/" + enc_spec["file"].str, threads);
    Session dec(env, dir + "/" + (*dec_spec)["file"].str, threads);
    const auto& rest = b.at("rest");
    const int64_t N = rest.shape[0], K = b.at("nbr").shape[1], S = b.at("joints").shape[0];
    const int64_t T = b.at("poses").shape[0], D = b.at("poses").shape[1], NB = b.at("betas").shape[0];
    int64_t W = 0;
    for (const auto& i : (*dec_spec)["inputs"].arr) if (i["name"].str == "window") W = static_cast<int64_t>(i["shape"].arr[1].num);
    auto t0 = std::chrono::steady_clock::now();
    // the encoder's inputs, fed by name (older encoders also take betas)
    std::vector<Input> ein;
    for (const auto& i : enc_spec["inputs"].arr) {
      const std::string& name = i["name"].str;
      if (name == "features")
        ein.push_back(input_from(enc_spec, name, b.at("features"), {1, N, b.at("features").shape[1]}));
      else if (name == "nbr") ein.push_back(input_from(enc_spec, name, b.at("nbr"), {N, K}));
      else if (name == "mask") ein.push_back(input_from(enc_spec, name, b.at("mask"), {N, K}));
      else if (name == "descriptor")
        ein.push_back(input_from(enc_spec, name, b.at("descriptor"), {1, b.at("descriptor").shape[0]}));
      else if (name == "betas") ein.push_back(input_from(enc_spec, name, b.at("betas"), {1, NB}));
      else throw std::runtime_error("the garment encoder takes '" + name + "', which this runtime cannot feed");
    }
    // its one output, without the batch axis, is the deformer input of the same name (g (N, S); older: P (N, S, F))
    const std::string code_name = enc_spec["outputs"].arr[0]["name"].str;
    std::vector<int64_t> pshape;
    std::vector<float> code = enc.run(ein, code_name, &pshape);
    release(ein);
    std::vector<Input> fixed;
    fixed.push_back(input_floats(code_name, code, std::vector<int64_t>(pshape.begin() + 1, pshape.end())));
    fixed.push_back(input_from(*dec_spec, "rest", rest, {N, 3}));
    fixed.push_back(input_from(*dec_spec, "nbr", b.at("nbr"), {N, K}));
    fixed.push_back(input_from(*dec_spec, "mask", b.at("mask"), {N, K}));
    bool residual = false;
    for (const auto& i : (*dec_spec)["inputs"].arr) if (i["name"].str == "log_wbody") residual = true;
    if (residual) fixed.push_back(input_from(*dec_spec, "log_wbody", b.at("log_wbody"), {N, S}));
    const float* poses = b.at("poses").as<float>();
    const float* trans = b.at("trans").as<float>();
    const float* betas = b.at("betas").as<float>();
    const float* joints = b.at("joints").as<float>();
    std::vector<float> frames(static_cast<size_t>(T * N * 3));
    const std::string out_name = (*dec_spec)["outputs"].arr[0]["name"].str;
    for (int64_t lo = 0; lo < T; lo += batch) {
      int64_t hi = std::min<int64_t>(lo + batch, T), B = hi - lo;
      std::vector<float> win(static_cast<size_t>(B * W * D)), bb(static_cast<size_t>(B * NB)),
          jj(static_cast<size_t>(B * S * 3)), tt(trans + lo * 3, trans + hi * 3);
      for (int64_t i = 0; i < B; ++i) {
        for (int64_t k = 0; k < W; ++k) {  // window[:, k] = the pose k frames back, the first frame before it
          int64_t src = std::max<int64_t>(lo + i - k, 0);
          std::copy(poses + src * D, poses + src * D + D, win.begin() + (i * W + k) * D);
        }
        std::copy(betas, betas + NB, bb.begin() + i * NB);
        std::copy(joints, joints + S * 3, jj.begin() + i * S * 3);
      }
      std::vector<Input> din;
      din.push_back(input_floats("window", win, {B, W, D}));
      din.push_back(input_floats("betas", bb, {B, NB}));
      din.push_back(input_floats("joints", jj, {B, S, 3}));
      din.push_back(input_floats("trans", tt, {B, 3}));
      std::vector<Input> all;
      for (auto& f : fixed) all.push_back(Input{f.name, {}, f.dims, f.value});
      for (auto& d : din) all.push_back(Input{d.name, {}, d.dims, d.value});
      std::vector<int64_t> vshape;
      std::vector<float> v = dec.run(all, out_name, &vshape);
      std::copy(v.begin(), v.end(), frames.begin() + lo * N * 3);
      release(din);
    }
    double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / T;
    release(fixed);
    write_pc2(out, frames, static_cast<int32_t>(T), static_cast<int32_t>(N));
    std::printf("%lld frames, %.2f ms/frame -> %s\n", static_cast<long long>(T), ms, out.c_str());
    if (do_check) {
      const auto& e = b.at("expected");
      const float* ex = e.as<float>();
      double max_abs = 0, max_ref = 0;
      for (size_t i = 0; i < frames.size(); ++i) {
        max_abs = std::max(max_abs, static_cast<double>(std::fabs(frames[i] - ex[i])));
        max_ref = std::max(max_ref, static_cast<double>(std::fabs(ex[i])));
      }
      std::printf("PARITY {\"max_abs\": %.9g, \"rel\": %.9g, \"ms_per_frame\": %.3f}\n", max_abs,
                  max_abs / max_ref, ms);
    }
    api->ReleaseEnv(env);
  } catch (const std::exception& e) {
    std::cerr << "Error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

// The cloth stage in the C++ runtime: the compiled kernel src/segadeform/body/_cloth.c (the file the Python runtime
// builds, with the collision kernel it calls, as segadeform.body._cloth), compiled as C into segadeform-run by
// CMakeLists.txt from where it is, and called here as `segadeform run --effects=+cloth` calls it: the garment's
// per-garment data from its rest shape and its rest distance from the body at rest, then the frames in batches with
// the state kept between them.  The method and its knobs: the C file's header and segadeform.cloth_settings.
#pragma once
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

extern "C" {
// _collide.c's entry points used here (its ABI 6)
void* sdc_create(const double* verts, int64_t nv, const int64_t* faces, int64_t nf, int64_t leaf_size);
void sdc_free(void* h);
int64_t sdc_n_nodes(const void* h);
void sdc_refit(const void* h, const double* verts, double* box);
void sdc_query(const void* h, const double* verts, const double* box, const double* pts, int64_t i0, int64_t i1,
               double* sd, double* closest, double* normal, int64_t* face);
// _cloth.c's (its ABI 15)
int64_t scl_abi(void);
int64_t scl_n_settings(void);
int64_t scl_setup(const double* rest, int64_t n, const int64_t* faces, int64_t nf, const double* rest_sd,
                  double attachment, double max_distance, int64_t* edges, double* rest_len, int64_t* nptr,
                  int64_t* nidx, double* radius, int64_t* anchor, double* tether, int64_t* weld);
int64_t scl_step(int64_t n, int64_t ne, const int64_t* edges, const double* rest_len, const int64_t* nptr,
                 const int64_t* nidx, const double* radius, const int64_t* anchor, const double* tether,
                 const int64_t* weld, int64_t nf, const int64_t* faces, const double* settings, const void* collider, int64_t nv,
                 const double* body, int64_t nb, const double* target, double* out, double* state, int64_t* info);
}

namespace sgd {

// A number as Python and Node print it (1, 0.03, 1e-06, 20000, 0.123456789, 1e+30): the fewest significant digits
// that read back as the same value, positional below 1e16 (std::to_string's %f printed 20000.000000, and 1e30 with
// 31 digits; a bare %g, 2e+04).  `Real`: double, or float (0.1f is 0.1, not the double nearest it, 0.100000001).
template <typename Real>
inline std::string shortest_of(Real x) {
  if (x != x) return "nan";  // (printf's -nan for some)
  const int most = sizeof(Real) == sizeof(float) ? 9 : 17;
  char b[48];
  int p = 1;
  for (; p < most; ++p) {
    std::snprintf(b, sizeof b, "%.*e", p - 1, static_cast<double>(x));
    if (static_cast<Real>(std::strtod(b, nullptr)) == x) break;
  }
  std::snprintf(b, sizeof b, "%.*e", p - 1, static_cast<double>(x));
  const char* e = std::strchr(b, 'e');
  const int exp = e ? std::atoi(e + 1) : 0;
  if (exp >= p && exp < 16) p = exp + 1;  // 20000, not 2e+04
  std::snprintf(b, sizeof b, "%.*g", p, static_cast<double>(x));
  return b;
}
inline std::string shortest(double x) { return shortest_of(x); }
inline std::string shortest(float x) { return shortest_of(x); }

// The knobs, as segadeform.cloth_settings.ClothSettings (defaults and ranges); `--cloth K=V,...` changes them.
struct ClothSettings {
  std::map<std::string, double> v{{"iterations", 4},   {"stiffness", 1.0}, {"stretch", 0.03},  {"compress", 0.3},
                                  {"bending", 0.9},    {"damping", 0.1},   {"follow", 0.5},    {"gravity", 9.81},
                                  {"attachment", 0.02}, {"max_distance", 0.05}, {"reset", 0.25},
                                  {"backstop", 0.03}};

  void parse(const std::string& text) {
    static const std::map<std::string, std::pair<double, double>> range{
        {"iterations", {1, 64}}, {"stiffness", {0, 1}}, {"stretch", {0, 1}},    {"compress", {0, 1}},
        {"bending", {0, 1}},     {"damping", {0, 1}},   {"follow", {0, 1}},     {"gravity", {0, 100}},
        {"attachment", {0, 1}},  {"max_distance", {0, 1}}, {"reset", {1e-6, 1e3}},
        {"backstop", {0, 1}}};
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
      if (item.empty()) continue;
      const size_t eq = item.find('=');
      const std::string name = item.substr(0, eq);
      if (eq == std::string::npos || !range.count(name))
        throw std::runtime_error("unknown cloth setting (expected NAME=VALUE with NAME one of iterations, stiffness, "
                                 "stretch, compress, bending, damping, follow, gravity, attachment, max_distance, "
                                 "reset, backstop, got '" + item + "')");
      size_t used = 0;
      double x = 0;
      try {
        x = std::stod(item.substr(eq + 1), &used);
      } catch (const std::exception&) {
        used = 0;
      }
      const auto& r = range.at(name);
      if (used == 0 || used != item.size() - eq - 1 || !(std::isfinite(x) && x >= r.first && x <= r.second) ||
          (name == "iterations" && x != std::floor(x)))
        throw std::runtime_error("cloth " + name + " must be " + (name == "iterations" ? "an integer" : "a number") +
                                 " in [" + shortest(r.first) + ", " + shortest(r.second) + "] (got '" +
                                 item.substr(eq + 1) + "')");
      v[name] = x;
    }
  }
  // _cloth.c's settings array (its S_* order)
  std::vector<double> array(double margin, double dt) const {
    return {v.at("iterations"), v.at("stiffness"), v.at("stretch"), v.at("compress"), v.at("bending"),
            v.at("damping"),    v.at("gravity"),   dt,              margin,            v.at("reset"),
            v.at("follow"),     v.at("backstop")};
  }
};

class Cloth {
 public:
  // rest (N, 3) float64 (the garment asset's vertices), faces (F, 3) int32, the body at rest (V, 3) float32 (the body
  // graph at zero pose), the body's faces (F', 3) int32.
  Cloth(const double* rest, int64_t n, const int32_t* faces, int64_t nf, const float* rest_body, int64_t nv,
        const int32_t* body_faces, int64_t nbf, const ClothSettings& settings, double margin, double dt)
      : n_(n), nv_(nv) {
    if (scl_abi() != 15 || scl_n_settings() != 12)
      throw std::runtime_error("the cloth kernel is from another version (expected ABI 15, 12 settings)");
    if (n < 1 || nv < 1 || nbf < 1) throw std::runtime_error("the cloth stage needs a garment and a body");
    std::vector<double> rb(rest_body, rest_body + 3 * nv);
    std::vector<int64_t> bf(body_faces, body_faces + 3 * nbf), gf(faces, faces + 3 * nf);
    for (int64_t x : bf)
      if (x < 0 || x >= nv) throw std::runtime_error("body face index out of range");
    h_ = sdc_create(rb.data(), nv, bf.data(), nbf, 4);
    if (!h_) throw std::runtime_error("out of memory building the cloth stage's body collider");
    // each garment vertex's signed distance from the body at rest (the exact closest point)
    std::vector<double> box(static_cast<size_t>(6 * sdc_n_nodes(h_))), sd(n), cp(3 * n), cn(3 * n);
    std::vector<int64_t> face(n);
    sdc_refit(h_, rb.data(), box.data());
    sdc_query(h_, rb.data(), box.data(), rest, 0, n, sd.data(), cp.data(), cn.data(), face.data());
    const size_t cap = static_cast<size_t>(nf > 0 ? 3 * nf : 1);
    edges_.resize(2 * cap);
    rest_len_.resize(cap);
    nidx_.resize(2 * cap);
    nptr_.resize(n + 1);
    radius_.resize(n);
    anchor_.resize(n);
    tether_.resize(n);
    weld_.resize(n);
    ne_ = scl_setup(rest, n, gf.data(), nf, sd.data(), settings.v.at("attachment"), settings.v.at("max_distance"),
                    edges_.data(), rest_len_.data(), nptr_.data(), nidx_.data(), radius_.data(), anchor_.data(),
                    tether_.data(), weld_.data());
    if (ne_ == -1) throw std::runtime_error("out of memory in the cloth stage's setup");
    if (ne_ < 0) throw std::runtime_error("garment face index out of range");
    faces_ = gf;  // checked by scl_setup; the backstop's normals
    nf_ = nf;
    settings_ = settings.array(margin, dt);
    state_.assign(static_cast<size_t>(9 * n), 0.0);
  }
  ~Cloth() { sdc_free(h_); }
  Cloth(const Cloth&) = delete;
  Cloth& operator=(const Cloth&) = delete;

  // The next nb frames: frames (nb * N * 3 float32, changed in place: computed in float64 and rounded back, as
  // `segadeform run` writes them) against the posed body (nb * V * 3 float32).
  // With `trans` (nb * 3), frames and body are at the root and the stage steps them at that translation, added in
  // float64 (engine.hpp at_translation; Python's segadeform.runtime.translation).
  void step(float* frames, int64_t nb, const float* body, const float* trans = nullptr) {
    std::vector<double> y(frames, frames + nb * n_ * 3), b(body, body + nb * nv_ * 3), out(y.size());
    if (trans) {
      for (int64_t f = 0; f < nb; ++f)
        for (int c = 0; c < 3; ++c) {
          const double t = trans[3 * f + c];
          for (int64_t i = 0; i < n_; ++i) y[static_cast<size_t>((f * n_ + i) * 3 + c)] += t;
          for (int64_t i = 0; i < nv_; ++i) b[static_cast<size_t>((f * nv_ + i) * 3 + c)] += t;
        }
    }
    const int64_t status = scl_step(n_, ne_, edges_.data(), rest_len_.data(), nptr_.data(), nidx_.data(),
                                    radius_.data(), anchor_.data(), tether_.data(), weld_.data(), nf_, faces_.data(), settings_.data(),
                                    h_, nv_, b.data(),
                                    nb, y.data(), out.data(), state_.data(), info_);
    if (status == -1) throw std::runtime_error("out of memory in the cloth stage");
    if (status > 0)
      throw std::runtime_error("the cloth stage got NaN or inf at frame " + std::to_string(frames_ + status - 1) +
                               " (expected finite coordinates from the deformer and the body)");
    if (info_[1] > 0 && first_reset_ < 0) first_reset_ = frames_ + info_[4];
    for (size_t i = 0; i < out.size(); ++i) frames[i] = static_cast<float>(out[i]);
    frames_ += nb;
  }
  int64_t resets() const { return info_[1]; }
  int64_t contacts() const { return info_[2]; }
  int64_t pushed() const { return info_[3]; }
  int64_t traced() const { return info_[5]; }
  int64_t first_reset() const { return first_reset_; }

 private:
  void* h_ = nullptr;
  int64_t n_ = 0, nv_ = 0, ne_ = 0, nf_ = 0, frames_ = 0, first_reset_ = -1;
  std::vector<int64_t> edges_, nptr_, nidx_, anchor_, faces_, weld_;
  std::vector<double> rest_len_, radius_, tether_, settings_, state_;
  int64_t info_[6] = {0, 0, 0, 0, -1, 0};
};

}  // namespace sgd

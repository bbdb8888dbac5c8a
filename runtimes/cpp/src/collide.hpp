// Collisions in the C++ runtime: the compiled kernel src/segadeform/body/_collide.c (the file the Python runtime
// builds as segadeform.body._collide), compiled as C into segadeform-run by CMakeLists.txt from where it is, and
// called here.  The rule is `segadeform run`'s post-process: p' = closest + margin * n for every garment vertex
// inside the posed body or closer than `margin`, again for the vertices moved, up to 3 passes, with each vertex's
// correction carried from frame to frame (sdc_push_out_carried: a vertex deep in a limb keeps the side it was
// pushed to).
#pragma once
#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

extern "C" {
// _collide.c's entry points (its ABI 6: sdc_abi(); 6 since sdc_push_out_carried, 5 since pinched points deeper than SDC_PINCH stay, 4 since the cloth stage's lookups leave pinched cloth, 3 since buried surfaces are skipped, 2 since its own acos).
void* sdc_create(const double* verts, int64_t nv, const int64_t* faces, int64_t nf, int64_t leaf_size);
void sdc_free(void* h);
int64_t sdc_abi(void);
int64_t sdc_n_nodes(const void* h);
void sdc_refit(const void* h, const double* verts, double* box);
int64_t sdc_push_out(const void* h, const double* verts, const double* box, int64_t nb, double* pts, int64_t n,
                     int64_t i0, int64_t i1, double margin, int64_t iterations, uint8_t* moved);
int64_t sdc_push_out_carried(const void* h, const double* verts, const double* box, int64_t nb, double* pts,
                             int64_t n, int64_t i0, int64_t i1, double margin, int64_t iterations, uint8_t* moved,
                             double* carry);
}

namespace sgd {

// A body collider: the kernel's tree over the body's triangles, built once from one pose (any pose: only the
// tree's tightness depends on it, never a result), refitted per frame.  It holds each garment vertex's push-out
// correction of the last frame it pushed out (zero at the start): a new clip takes a new collider.
class Collider {
 public:
  // verts (V, 3) of one pose as float32 (the body graph's output), faces (F, 3) int32.
  Collider(const float* verts, int64_t nv, const int32_t* faces, int64_t nf) : nv_(nv) {
    if (sdc_abi() != 6) throw std::runtime_error("the collision kernel is from another version (expected ABI 6)");
    if (nv < 1 || nf < 1) throw std::runtime_error("the body has no vertices or no faces");
    std::vector<double> v(verts, verts + 3 * nv);
    std::vector<int64_t> f(faces, faces + 3 * nf);
    for (int64_t x : f)
      if (x < 0 || x >= nv)
        throw std::runtime_error("body face index out of range (expected 0.." + std::to_string(nv - 1) + ", got " +
                                 std::to_string(x) + ")");
    h_ = sdc_create(v.data(), nv, f.data(), nf, 4);
    if (!h_) throw std::runtime_error("out of memory building the body collider");
    n_nodes_ = sdc_n_nodes(h_);
  }
  ~Collider() { sdc_free(h_); }
  Collider(const Collider&) = delete;
  Collider& operator=(const Collider&) = delete;

  // push_out of B frames of N garment vertices (float32, B * N * 3, changed in place: computed in float64 and
  // rounded back, as `segadeform run` writes them) against the posed body (float32, B * V * 3).  The vertices are
  // split into `threads` ranges (every vertex's result is independent of the split).  The B frames follow the last
  // call's: the correction is carried (the same frames for any cut of a clip into calls).  Returns the number of
  // (frame, vertex) pairs moved.
  int64_t push_out(float* frames, int64_t B, int64_t N, const float* body, double margin, int threads,
                   int64_t iterations = 3) {
    std::vector<double> verts(body, body + B * nv_ * 3), pts(frames, frames + B * N * 3);
    std::vector<double> box(static_cast<size_t>(B * n_nodes_ * 6));
    for (int64_t f = 0; f < B; ++f) sdc_refit(h_, verts.data() + f * nv_ * 3, box.data() + f * n_nodes_ * 6);
    std::vector<uint8_t> moved(static_cast<size_t>(B * N), 0);
    if (carry_.size() != static_cast<size_t>(N * 3)) carry_.assign(static_cast<size_t>(N * 3), 0.0);
    const int64_t k = threads <= 1 ? 1 : std::min<int64_t>(N, 4 * static_cast<int64_t>(threads));
    auto range = [&](int64_t j) {
      sdc_push_out_carried(h_, verts.data(), box.data(), B, pts.data(), N, j * N / k, (j + 1) * N / k, margin,
                           iterations, moved.data(), carry_.data());
    };
    if (k <= 1) {
      range(0);
    } else {  // ranges handed to the threads in turn (a range near the body costs more than one far from it)
      std::vector<std::thread> pool;
      for (int t = 0; t < threads; ++t)
        pool.emplace_back([&, t] { for (int64_t j = t; j < k; j += threads) range(j); });
      for (auto& th : pool) th.join();
    }
    int64_t total = 0;
    for (uint8_t m : moved) total += m;
    for (size_t i = 0; i < pts.size(); ++i) frames[i] = static_cast<float>(pts[i]);
    return total;
  }

 private:
  void* h_ = nullptr;
  int64_t nv_ = 0, n_nodes_ = 0;
  std::vector<double> carry_;  // (N, 3) each vertex's correction at the last frame pushed out
};

}  // namespace sgd

// segadeform's C++ library: play a garment on a motion that arrives a chunk at a time, in a program of one's own
// (a game engine, a DCC plug-in, a server).  The same engine as the segadeform-run program and the Node/browser
// Player (runtimes/node/src/core.js): a model package, a garment asset (.sgda from `segadeform garment export`), then
// poses pushed as they come; every frame the deformer, the body posed by the package's body graph, and the cloth
// stage or collisions the effects name, their state carried from push to push.
//
//   #include <segadeform/player.hpp>
//   segadeform::PlayerOptions opt;
//   opt.effects = "+cloth";          // the package's default effects with the cloth stage added
//   opt.fps = 30;                    // the motion's frame rate (the cloth stage's time step)
//   segadeform::Player player("samples/models/default", "out/dress_b.sgda", opt);
//   std::vector<float> frame = player.push(poses, trans, 1);   // poses 1 * joints() * 3, trans 1 * 3
//
// Frames are those of one call over the whole motion (segadeform-run's, and so `segadeform run`'s), bit for bit when
// every push is a multiple of `batch` frames (batch = 1 for a frame at a time); other sizes run other onnxruntime
// batch sizes (1e-6 m), which a push-out in a crease can turn into millimetres.  Errors are std::runtime_error with
// one line saying what was expected and what came.  Build: link the CMake target `segadeform` (runtimes/cpp).
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace segadeform {

struct PlayerOptions {
  // Effects as `segadeform run --effects` reads them: "" for the package's default (its model's effects, and
  // collisions when it has a body graph), a complete list ("lbs,dynamics,wrinkles,cloth"), "none", or signed
  // changes to the default ("+cloth", "dqs,-wrinkles").
  std::string effects;
  double collision_margin = 0.004;  // metres, [0, 1): collisions' margin, and the cloth stage's contact margin
  std::string cloth;                // the cloth stage's knobs, "K=V,..." as `--cloth` (needs cloth in the effects)
  double fps = 0;                   // the motion's frame rate, 1..1000: needed by the cloth stage
  int batch = 8;                    // frames per onnxruntime call
  int threads = 1;                  // onnxruntime's intra-op threads and collisions' threads
  bool body = false;                // also return the posed body from push()
  bool force = false;               // play a garment asset exported with --force for a body it does not sit on
};

// What the player did: frames pushed and collisions' count since it opened; the cloth stage's since the last reset().
struct Counts {
  int64_t frames = 0;    // frames pushed
  int64_t moved = 0;     // collisions: vertex-frames pushed out
  int64_t contacts = 0;  // the cloth stage: vertex-frames in contact
  int64_t pushed = 0;    // ... pushed out after its sweeps
  int64_t traced = 0;    // ... traced out by its backstop
  int64_t resets = 0;    // ... times it started again from the network's frame (the garment jumped)
};

// A motion file (.sgdm from `segadeform motion export`): poses (frames * joints * 3, axis-angle), trans (frames * 3),
// its frame rate.  read_motion checks it against the garment asset it will play (the same body and shape), as
// segadeform-run does; `force` plays a motion made for another body or shape (warnings() says so).
struct Motion {
  std::vector<float> poses, trans;
  int64_t frames = 0, joints = 0;
  double fps = 0;
  std::vector<std::string> warnings;
};
Motion read_motion(const std::string& motion_file, const std::string& garment_asset, bool force = false);

class Player {
 public:
  Player(const std::string& package_dir, const std::string& garment_asset, const PlayerOptions& options = {});
  ~Player();
  Player(Player&&) noexcept;
  Player& operator=(Player&&) noexcept;
  Player(const Player&) = delete;
  Player& operator=(const Player&) = delete;

  // The next `frames` frames: poses (frames * joints() * 3, axis-angle per joint, on the body's skeleton; any angle,
  // read modulo 2 pi as motion files are) and trans (frames * 3, metres, within 10 km).  Returns the garment's
  // vertices (frames * vertices() * 3); with options.body, `body` gets the posed body (frames * body_vertices() * 3).
  std::vector<float> push(const float* poses, const float* trans, int64_t frames, std::vector<float>* body = nullptr);
  // A new clip: no motion history; the cloth stage starts again from the network's frame, the collider anew.
  void reset();

  int64_t vertices() const;       // the garment's
  int64_t joints() const;         // the skeleton's
  int64_t body_vertices() const;  // the posed body's (0 when no stage or option needs it)
  const std::vector<int32_t>& faces() const;  // the garment's triangles (F * 3)
  std::string effects() const;    // the effects that run, as a list ("lbs,dynamics,wrinkles,cloth")
  Counts counts() const;
  const std::vector<std::string>& warnings() const;  // what `force` let through

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace segadeform

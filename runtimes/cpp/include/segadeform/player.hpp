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
// Frames are those of `segadeform-run --batch B` and `segadeform run --batch B` over the whole motion, bit for bit,
// when every push is a multiple of batch() (options.batch = B, lowered for a garment over 32,768 / B vertices as every
// runtime lowers it; B = 1 for a frame at a time).  Another B, or pushes of other
// sizes, run the network on other onnxruntime batch sizes, which round differently (1e-6 m); collisions' push-out and
// above all the cloth stage, which carries its state from frame to frame, can grow that into millimetres or
// centimetres (32 mm measured between --batch 1 and 8 with the cloth stage on a 120 fps CMU walk): compare with the
// same B.  Errors are std::runtime_error with one line saying what was expected and what came.
//
// Conventions: metres, +Y up, the body's skeleton (docs/package.md: the 24 joints in SMPL order, the motion file's
// joint_names); pose zero is the body's rest pose (a T-pose) and trans moves the root, as in the motion files that
// `segadeform motion export` writes.  Vertices come in the garment asset's order.  One Player is not to be used by
// two threads at once; separate Players may run in separate threads.  A moved-from Player throws on every call.
//
// Build: the CMake target `segadeform` (add_subdirectory(runtimes/cpp) with ONNXRUNTIME_INCLUDE_DIR and
// ONNXRUNTIME_LIBRARY set, as tools/onnxruntime_cpp.sh sets them; SEGADEFORM_PROGRAMS=OFF leaves out segadeform-run
// and segadeform-play).
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
  int64_t start_frame = 0;  // the first frame's number in its source (`motion export --frames A:B`: A)
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
  // The same with the sizes checked: poses.size() must be frames * joints() * 3 and trans.size() frames * 3 (the
  // pointer form trusts the caller's count).
  std::vector<float> push(const std::vector<float>& poses, const std::vector<float>& trans,
                          std::vector<float>* body = nullptr);
  // A new clip: no motion history; the cloth stage starts again from the network's frame, the collider anew.  After
  // a push that threw part-way (onnxruntime ran out of memory ...), every push is refused until reset().
  void reset();

  int64_t vertices() const;       // the garment's
  int64_t joints() const;         // the skeleton's
  int batch() const;              // frames per network call: options.batch, lowered for a big garment
  int64_t body_vertices() const;  // the posed body's (0 when no stage or option needs it)
  const std::vector<int32_t>& faces() const;  // the garment's triangles (F * 3)
  const std::vector<int32_t>& body_faces() const;  // the posed body's triangles (with options.body; else empty)
  std::string effects() const;    // the effects that run, as a list ("lbs,dynamics,wrinkles,cloth": the cloth
                                  // stage's contact replaces collisions)
  Counts counts() const;
  const std::vector<std::string>& warnings() const;  // what `force` let through

 private:
  struct Impl;
  Impl& impl() const;  // throws on a moved-from Player
  std::unique_ptr<Impl> impl_;
};

}  // namespace segadeform

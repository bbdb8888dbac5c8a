// segadeform::Player (include/segadeform/player.hpp) on the engine segadeform-run uses (engine.hpp): the garment
// asset read and checked once, then a Stream pushed a chunk at a time.
#include <segadeform/player.hpp>

#include "engine.hpp"

namespace segadeform {

using namespace sgd::engine;

namespace {

// the onnxruntime API and one environment for the process (created on first use, kept: onnxruntime wants one)
OrtEnv* environment() {
  static OrtEnv* env = [] {
    if (!api) api = OrtGetApiBase()->GetApi(ORT_API_VERSION);
    if (!api)
      throw std::runtime_error("the onnxruntime library is older than the headers (API " +
                               std::to_string(ORT_API_VERSION) + ")");
    OrtEnv* e = nullptr;
    check(api->CreateEnv(ORT_LOGGING_LEVEL_WARNING, "segadeform", &e));
    return e;
  }();
  return env;
}

}  // namespace

namespace {
void bad_count(const std::string& what, int64_t got, int64_t want) {
  throw std::runtime_error("push: " + what + " has " + std::to_string(got) + " values (expected " + std::to_string(want) +
                           ")");
}
}  // namespace

struct Player::Impl {
  Package pkg;
  sgd::Bundle asset;
  Scene sc;
  std::unique_ptr<Stream> stream;
  PlayerOptions opt;
  std::vector<int32_t> faces;

  std::vector<int32_t> body_faces;

  Impl(const std::string& package_dir, const std::string& garment, const PlayerOptions& o)
      : pkg(package_dir), asset(sgd::read_bundle(garment)), opt(o) {
    sc = garment_of_asset(asset, garment, o.force);
    check_training_body(pkg, o.force, sc.warnings, "the option force");
    if (o.batch < 1) throw std::runtime_error("batch must be an integer >= 1 (got " + std::to_string(o.batch) + ")");
    if (o.threads < 1)
      throw std::runtime_error("threads must be an integer >= 1 (got " + std::to_string(o.threads) + ")");
    StreamOptions so;
    so.effects = o.effects.empty() ? pkg.default_effects() : parse_effects(o.effects, pkg.default_effects());
    if (!o.cloth.empty()) {
      if (!so.effects.cloth)
        throw std::runtime_error("the option cloth sets the cloth stage's knobs, but the stage is off (name cloth in "
                                 "the effects)");
      so.cloth.parse(o.cloth);
    }
    if (so.effects.cloth && !(o.fps >= 1 && o.fps <= 1000))
      throw std::runtime_error("the cloth stage needs the motion's frame rate (expected the option fps, 1..1000, got " +
                               sgd::shortest(o.fps) + ")");
    // said here, its number as written (the engine's own check prints it with %f: 5.000000)
    if (!(o.collision_margin >= 0 && o.collision_margin < 1))
      throw std::runtime_error("the collision margin must be in [0, 1) metres (got " + sgd::shortest(o.collision_margin) +
                               ")");
    so.margin = o.collision_margin;
    so.fps = o.fps;
    so.batch = o.batch;
    so.threads = o.threads;
    so.body = o.body;
    stream.reset(new Stream(environment(), pkg, sc, so));
    const int32_t* f = sc.faces->as<int32_t>();
    faces.assign(f, f + sc.faces->count());
    if (o.body) body_faces = stream->body_faces();
  }
};

// the implementation, or the error of a moved-from Player (it has none)
Player::Impl& Player::impl() const {
  if (!impl_) throw std::runtime_error("this Player was moved from (expected a Player that holds a garment)");
  return *impl_;
}

Player::Player(const std::string& package_dir, const std::string& garment_asset, const PlayerOptions& options)
    : impl_(new Impl(package_dir, garment_asset, options)) {}
Player::~Player() = default;
Player::Player(Player&&) noexcept = default;
Player& Player::operator=(Player&&) noexcept = default;

std::vector<float> Player::push(const std::vector<float>& poses, const std::vector<float>& trans,
                                std::vector<float>* body) {
  const int64_t D = impl().sc.D, frames = static_cast<int64_t>(trans.size() / 3);
  if (trans.size() % 3 != 0 || frames < 1)
    throw std::runtime_error("push: trans has " + std::to_string(trans.size()) +
                             " values (expected 3 per frame, at least one frame)");
  if (static_cast<int64_t>(poses.size()) != frames * D) bad_count("poses", static_cast<int64_t>(poses.size()), frames * D);
  return push(poses.data(), trans.data(), frames, body);
}

std::vector<float> Player::push(const float* poses, const float* trans, int64_t frames, std::vector<float>* body) {
  Impl& m = impl();
  const int64_t D = m.sc.D, N = m.sc.N;
  if (frames < 1) throw std::runtime_error("push: expected at least one frame (got " + std::to_string(frames) + ")");
  const int64_t widest = std::max<int64_t>({N * 3, D, m.opt.body ? m.stream->V() * 3 : 0});
  if (frames > (int64_t{1} << 31) / widest)  // no count overflows, no output (the body's too) past 2^31 values
    throw std::runtime_error("push: too many frames at once (got " + std::to_string(frames) + "; push fewer)");
  if (!poses || !trans) throw std::runtime_error("push: expected poses and trans (got a null pointer)");
  std::vector<float> p(poses, poses + frames * D);
  for (size_t i = 0; i < p.size(); ++i)
    if (!std::isfinite(p[i]))
      throw std::runtime_error("push: poses contain NaN or inf (at value " + std::to_string(i) + ")");
  for (int64_t i = 0; i < frames * 3; ++i)
    if (!(std::fabs(trans[i]) <= 1e4f))
      throw std::runtime_error("push: trans must be finite and within 10 km (got " + sgd::shortest(trans[i]) +
                               " at value " + std::to_string(i) + ")");
  canonical_axis_angle(p);  // every rotation written one way, as motion files are read
  std::vector<float> out(static_cast<size_t>(frames * N * 3));
  float* b = nullptr;
  if (body) {
    if (!m.opt.body) throw std::runtime_error("push: the posed body was asked for, but the player was opened without "
                                              "the option body");
    body->assign(static_cast<size_t>(frames * m.stream->V() * 3), 0.f);
    b = body->data();
  }
  m.stream->push(p.data(), trans, frames, out.data(), b);
  return out;
}

void Player::reset() { impl().stream->reset(); }

int64_t Player::vertices() const { return impl().sc.N; }
int64_t Player::joints() const { return impl().sc.S; }
int Player::batch() const { return impl().stream->batch(); }
int64_t Player::body_vertices() const { return impl().stream->V(); }
const std::vector<int32_t>& Player::faces() const { return impl().faces; }
const std::vector<int32_t>& Player::body_faces() const { return impl().body_faces; }
const std::vector<std::string>& Player::warnings() const { return impl().sc.warnings; }

std::string Player::effects() const {
  const Effects& e = impl().stream->effects();
  return e.skinning + (e.dynamics ? ",dynamics" : "") + (e.wrinkles ? ",wrinkles" : "") +
         (e.collisions ? ",collisions" : "") + (e.cloth ? ",cloth" : "");
}

Counts Player::counts() const {
  Counts c;
  const Stream& s = *impl().stream;
  c.frames = s.frames();
  c.moved = s.moved();
  if (const sgd::Cloth* st = s.cloth()) {
    c.contacts = st->contacts();
    c.pushed = st->pushed();
    c.traced = st->traced();
    c.resets = st->resets();
  }
  return c;
}

Motion read_motion(const std::string& motion_file, const std::string& garment_asset, bool force) {
  const sgd::Bundle a = sgd::read_bundle(garment_asset), m = sgd::read_bundle(motion_file);
  Scene s = garment_of_asset(a, garment_asset, true);  // the asset's own fit is the Player's to refuse
  s.warnings.clear();
  motion_into(s, m, motion_file, force);
  Motion r;
  r.poses = floats(m.at("poses"));  // as written: push() makes them canonical, once (a second pass can flip a
                                    // rotation just above pi back: not what segadeform-run plays)
  r.trans = std::move(s.trans);
  r.frames = s.T;
  r.joints = s.S;
  r.fps = s.fps;
  r.start_frame = static_cast<int64_t>(s.start_frame);
  r.warnings = std::move(s.warnings);
  return r;
}

}  // namespace segadeform

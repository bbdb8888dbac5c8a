// The C++ library's own checks (run by tests/runtimes/test_cloth.py with a package, a garment asset and a motion
// file): the API's refusals are std::runtime_error with one line, never a crash, and what it promises holds --
// reset() gives a fresh player's frames, two players in one process do not disturb each other, a moved Player goes
// on and the moved-from one refuses.  Prints one line per check ("ok NAME" or "FAIL NAME: why"); exit 1 on a failure.
//
//   segadeform-player-test PACKAGE G.sgda M.sgdm
#include <segadeform/player.hpp>

#include <algorithm>
#include <cstdio>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace {
int failures = 0;

void check(const std::string& name, bool ok, const std::string& why = "") {
  std::printf("%s %s%s\n", ok ? "ok" : "FAIL", name.c_str(), ok ? "" : (": " + why).c_str());
  if (!ok) ++failures;
}

// `f` throws std::runtime_error whose one-line message holds `words`
void refuses(const std::string& name, const std::function<void()>& f, const std::string& words) {
  try {
    f();
    check(name, false, "no error");
  } catch (const std::runtime_error& e) {
    const std::string w = e.what();
    check(name, w.find(words) != std::string::npos && w.find('\n') == std::string::npos, "message: " + w);
  } catch (const std::exception& e) {
    check(name, false, std::string("not a std::runtime_error: ") + e.what());
  }
}
}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: segadeform-player-test PACKAGE G.sgda M.sgdm\n");
    return 2;
  }
  const std::string pkg = argv[1], garment = argv[2];
  try {
    const segadeform::Motion m = segadeform::read_motion(argv[3], garment);
    if (m.frames < 12) throw std::runtime_error("the test needs a motion of at least 12 frames");
    const int64_t D = 3 * m.joints, T = 12;
    segadeform::PlayerOptions o;
    o.batch = 4;
    segadeform::Player a(pkg, garment, o);
    const std::vector<float> first = a.push(m.poses.data(), m.trans.data(), T);
    // sizes checked by the vector form; the pointer form's count checked for sense
    const std::vector<float> p1(m.poses.begin(), m.poses.begin() + D), t1(m.trans.begin(), m.trans.begin() + 3);
    refuses("push of poses one value short", [&] { a.push(std::vector<float>(p1.begin(), p1.end() - 1), t1); },
            "poses has");
    refuses("push of trans not whole frames", [&] { a.push(p1, std::vector<float>{0.f, 0.f}); }, "trans has");
    refuses("push of no frame", [&] { a.push(m.poses.data(), m.trans.data(), 0); }, "at least one frame");
    refuses("push of 2^60 frames", [&] { a.push(m.poses.data(), m.trans.data(), int64_t{1} << 60); }, "too many");
    refuses("push of a null pointer", [&] { a.push(nullptr, m.trans.data(), 1); }, "null pointer");
    refuses("the body without options.body", [&] {
      std::vector<float> b;
      a.push(p1.data(), t1.data(), 1, &b);
    }, "option body");
    std::vector<float> nan = p1;
    nan[5] = 0.f / 0.f;
    refuses("NaN poses", [&] { a.push(nan, t1); }, "NaN");
    // numbers said as written, not with %f (20000.000000, 5.000000: a new user's trial)
    std::vector<float> far = t1;
    far[1] = 20000.5f;
    refuses("trans beyond 10 km said as written", [&] { a.push(p1, far); }, "(got 20000.5 at value 1)");
    // reset: a new clip gives a fresh player's frames; a second player in the same process the same again
    a.reset();
    check("reset gives the first frames again", a.push(m.poses.data(), m.trans.data(), T) == first);
    // a second player, pushed in alternation with the first, chunk by chunk: each gives the first frames
    segadeform::Player b(pkg, garment, o);
    a.reset();
    std::vector<float> fa, fb;
    for (int64_t t = 0; t < 8; t += 4) {
      const std::vector<float> x = a.push(m.poses.data() + t * D, m.trans.data() + t * 3, 4);
      const std::vector<float> y = b.push(m.poses.data() + t * D, m.trans.data() + t * 3, 4);
      fa.insert(fa.end(), x.begin(), x.end());
      fb.insert(fb.end(), y.begin(), y.end());
    }
    check("two players interleaved", fa == fb && fa == std::vector<float>(first.begin(), first.begin() + fa.size()));
    a.reset();
    (void)a.push(m.poses.data(), m.trans.data(), 4);
    // moving: the new owner goes on; the moved-from player refuses every call
    segadeform::Player c(std::move(a));
    const size_t four = static_cast<size_t>(4 * c.vertices() * 3);  // four frames' values
    // the batch it runs: the option's, lowered to at most 32,768 vertex-frames a call, as every runtime lowers it
    check("batch() is the batch it runs",
          c.batch() == static_cast<int>(std::max<int64_t>(1, std::min<int64_t>(4, 32768 / c.vertices()))));
    check("a moved player goes on", c.push(m.poses.data() + 4 * D, m.trans.data() + 12, 4) ==
                                        std::vector<float>(first.begin() + four, first.begin() + 2 * four));
    refuses("a moved-from player's push", [&] { a.push(p1, t1); }, "moved from");
    refuses("a moved-from player's vertices()", [&] { (void)a.vertices(); }, "moved from");
    // opening: every problem one line
    refuses("a package that does not exist", [&] { segadeform::Player x(pkg + "/nope", garment, o); }, "nope");
    refuses("a motion file as the garment", [&] { segadeform::Player x(pkg, argv[3], o); }, "not a garment asset");
    refuses("a folder as the garment", [&] { segadeform::Player x(pkg, pkg, o); }, pkg);
    segadeform::PlayerOptions bad = o;
    bad.effects = "lbs,cloth";
    refuses("the cloth stage without fps", [&] { segadeform::Player x(pkg, garment, bad); }, "frame rate");
    bad.effects = "lbs,sparkles";
    refuses("an unknown effect", [&] { segadeform::Player x(pkg, garment, bad); }, "unknown effect");
    bad.effects = "lbs,cloth";
    bad.fps = 20000;
    refuses("an fps out of range said as written", [&] { segadeform::Player x(pkg, garment, bad); }, "got 20000)");
    bad = o;
    bad.collision_margin = 5;
    refuses("a margin out of range said as written", [&] { segadeform::Player x(pkg, garment, bad); },
            "the collision margin must be in [0, 1) metres (got 5)");
    bad.collision_margin = 1e30;
    refuses("a huge margin said as written", [&] { segadeform::Player x(pkg, garment, bad); }, "(got 1e+30)");
    segadeform::PlayerOptions cl = o;
    cl.effects = "+cloth";
    cl.fps = m.fps;
    cl.body = true;
    segadeform::Player d(pkg, garment, cl);
    check("cloth replaces collisions in effects()", d.effects().find("collisions") == std::string::npos &&
                                                         d.effects().find("cloth") != std::string::npos, d.effects());
    check("body faces with options.body", !d.body_faces().empty() && d.body_faces().size() % 3 == 0);
  } catch (const std::exception& e) {
    check("no unexpected error", false, e.what());
  }
  return failures ? 1 : 0;
}

// segadeform-run: the C++ runtime.  A model package and a garment asset (.sgda) with a motion file (.sgdm) in,
// PC2 point caches of the garment (and, with --body-out, of the body posed by the package's body graph, its rest mesh
// beside it as BODY.obj) out:
//
//   segadeform-run --package DIR --garment G.sgda --motion M.sgdm -o OUT.pc2 [--body-out BODY.pc2]
//                  [--effects lbs|dqs,dynamics,wrinkles,collisions,cloth] [--collision-margin M] [--cloth K=V,..]
//                  [--batch N] [--threads N]
//   segadeform-run PACKAGE_DIR BUNDLE.sgdb -o OUT.pc2 [--batch N] [--threads N] [--check]
//
// (the second form: a scene bundle from `segadeform bundle`; --check compares the frames with its `expected`
// array, the Python runtime's output, and prints the error).  Without --effects: the model's own effects and
// collisions when the package has a body graph, as `segadeform run` without --effects.  Collisions push the
// garment out of the posed body with the compiled kernel src/segadeform/body/_collide.c (collide.hpp; margin
// 0.004 m unless --collision-margin).  The cloth stage (off unless named; cloth.hpp, the compiled kernel
// src/segadeform/body/_cloth.c) replaces the push-out when named, its knobs from --cloth.  Built on the onnxruntime C
// API (the shared library, C++17, no other dependency).  Formats: docs/package.md.  The engine (engine.hpp) is
// the library's too: this program pushes the motion through a sgd::engine::Stream a batch at a time, as a
// program of one's own pushes it through segadeform::Player (include/segadeform/player.hpp).
#include <unistd.h>

#include <csignal>
#include <cstring>
#include <set>

#include "engine.hpp"

using namespace sgd::engine;

namespace {

// The temporaries this run writes its outputs to, removed when a signal stops it (Ctrl-C, kill): they were left
// behind, 172 MB of a body cache (a developer's trial).  Fixed buffers: the handler only calls unlink.
// The folders this run made for its outputs (deepest first) go too where they are still empty, as `segadeform run`
// removes them (segadeform.io.atomic.make_folders): rmdir removes nothing else.
constexpr int MAX_TEMPS = 8;
constexpr int MAX_DIRS = 32;
char g_temps[MAX_TEMPS][4096];
volatile std::sig_atomic_t g_ntemps = 0;
char g_dirs[MAX_DIRS][4096];
volatile std::sig_atomic_t g_ndirs = 0;

void remove_temporaries_and_made_folders() {
  for (int i = 0; i < g_ntemps; ++i) ::unlink(g_temps[i]);
  for (int i = 0; i < g_ndirs; ++i) ::rmdir(g_dirs[i]);  // not empty: left
}

extern "C" void remove_temporaries_and_stop(int sig) {
  remove_temporaries_and_made_folders();
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

void remove_temporaries_on_signals(const std::vector<std::string>& outputs) {
  namespace fs = sgd::outputs_detail::fs;
  std::vector<std::string> dirs;
  for (const auto& o : outputs) {
    const std::string t = sgd::temporary_name(o);
    if (g_ntemps < MAX_TEMPS && t.size() < sizeof g_temps[0]) {
      std::memcpy(g_temps[g_ntemps], t.c_str(), t.size() + 1);
      g_ntemps = g_ntemps + 1;
    }
    // the folders it goes in, made here one level at a time: those this call made (not one someone else made
    // meanwhile) are noted, deepest first
    std::error_code ec;
    std::vector<std::string> missing;
    for (fs::path d = fs::absolute(fs::path(o), ec).parent_path(); !d.empty() && !fs::exists(d, ec);
         d = d.parent_path()) {
      if (d == d.parent_path()) break;
      missing.push_back(d.string());
    }
    for (auto it = missing.rbegin(); it != missing.rend(); ++it)
      if (::mkdir(it->c_str(), 0777) == 0) dirs.insert(dirs.begin(), *it);
  }
  for (const auto& d : dirs) {
    if (g_ndirs < MAX_DIRS && d.size() < sizeof g_dirs[0]) {
      std::memcpy(g_dirs[g_ndirs], d.c_str(), d.size() + 1);
      g_ndirs = g_ndirs + 1;
    }
  }
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, remove_temporaries_and_stop);
}

const char* USAGE =
    "usage: segadeform-run --package DIR --garment G.sgda --motion M.sgdm -o OUT.pc2 [--body-out BODY.pc2]\n"
    "                      [--effects lbs|dqs,dynamics,wrinkles,collisions,cloth] [--collision-margin M]\n"
    "                      [--cloth K=V,..] [--batch N] [--threads N] [--up y|z] [--output-units U] [--force]\n"
    "       segadeform-run PACKAGE_DIR BUNDLE.sgdb -o OUT.pc2 [--batch N] [--threads N] [--up y|z] [--output-units U]\n"
    "                      [--check]\n";

// A whole decimal integer (std::stoi read "8x" as 8 and "2.5" as 2: a user's trial); else invalid_argument.
int whole_int(const std::string& t) {
  size_t end = 0;
  const int v = std::stoi(t, &end);
  if (end != t.size() || t.find_first_of(".eE") != std::string::npos) throw std::invalid_argument(t);
  return v;
}

// Metres per unit of --output-units (segadeform.io.writer.output_unit): a name or a number in [1e-4, 1]; else NaN.
double metres_per_unit(const std::string& text) {
  std::string t;
  for (char c : text)
    if (!std::isspace(static_cast<unsigned char>(c))) t += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  static const std::map<std::string, double> names{{"m", 1.0},     {"dm", 0.1},      {"cm", 0.01},
                                                   {"mm", 0.001},  {"inch", 0.0254}, {"ft", 0.3048}};
  if (names.count(t)) return names.at(t);
  char* e = nullptr;
  const double f = t.empty() ? NAN : std::strtod(t.c_str(), &e);
  return (e && *e == '\0' && f >= 1e-4 && f <= 1.0) ? f : NAN;
}

// The written coordinates (segadeform.io.writer.to_output): +Y up metres turned to +Z up ((x, y, z) -> (x, -z, y))
// and divided by the unit, in float64, then held as T (the point caches' float32; the rest OBJ's double, as Python's).
template <class T>
std::vector<T> to_output(const float* a, int64_t n, bool z_up, double unit) {
  std::vector<T> out(static_cast<size_t>(n));
  for (int64_t i = 0; i + 2 < n; i += 3) {
    const double x = a[i], y = a[i + 1], z = a[i + 2];
    out[i] = static_cast<T>(x / unit);
    out[i + 1] = static_cast<T>((z_up ? -z : y) / unit);
    out[i + 2] = static_cast<T>((z_up ? y : z) / unit);
  }
  return out;
}

// A triangle mesh as OBJ, as segadeform.io.obj.write_obj writes it (9 significant digits, 1-based faces).
template <class T>
void write_obj(const std::string& path, const std::vector<T>& v, const std::vector<int32_t>& f) {
  std::ofstream o(path, std::ios::binary);
  o << "# segadeform OBJ: " << v.size() / 3 << " vertices, " << f.size() / 3 << " triangles\n";
  char line[96];
  for (size_t i = 0; i + 2 < v.size(); i += 3) {
    std::snprintf(line, sizeof line, "v %.9g %.9g %.9g\n", static_cast<double>(v[i]), static_cast<double>(v[i + 1]),
                  static_cast<double>(v[i + 2]));
    o << line;
  }
  for (size_t i = 0; i + 2 < f.size(); i += 3) o << "f " << f[i] + 1 << " " << f[i + 1] + 1 << " " << f[i + 2] + 1 << "\n";
  if (!o) throw std::runtime_error(path + ": cannot write");
}


}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args = sgd::command_args(argc, argv);  // --name=value is --name value
  for (const auto& a : args)
    if (a == "--help" || a == "-h") {
      std::cout << USAGE;
      return 0;
    }
  std::string out, package, garment, motion, body_out, effects, cloth, up = "y", units_text;
  bool effects_given = false;  // `--effects ""` is an empty list (refused), not "not given"
  int batch = 8, threads = 1;
  double margin = DEFAULT_COLLISION_MARGIN;
  bool margin_given = false;
  std::string margin_text;  // as the user wrote it (a message quotes it so)
  bool do_check = false;
  bool force = false;  // a motion made for another body or shape: played, with a warning
  std::vector<std::string> pos;
  std::string current;  // the option being read (a bad value names it)
  std::set<std::string> seen;  // an option given twice is a usage error, as in Node and Python (the last one won)
  std::string repeated;
  try {
    for (size_t i = 0; i < args.size(); ++i) {
      const bool more = i + 1 < args.size();
      current = args[i];
      if (args[i].rfind("-", 0) == 0 && std::string(USAGE).find(args[i] + " ") != std::string::npos &&
          !seen.insert(args[i]).second && repeated.empty())
        repeated = args[i];
      if (args[i] == "-o" && more) out = args[++i];
      else if (args[i] == "--batch" && more) batch = whole_int(args[++i]);
      else if (args[i] == "--threads" && more) threads = whole_int(args[++i]);
      else if (args[i] == "--package" && more) package = args[++i];
      else if (args[i] == "--garment" && more) garment = args[++i];
      else if (args[i] == "--motion" && more) motion = args[++i];
      else if (args[i] == "--body-out" && more) body_out = args[++i];
      else if (args[i] == "--effects" && more) effects = args[++i], effects_given = true;
      else if (args[i] == "--cloth" && more) cloth = args[++i];
      else if (args[i] == "--up" && more) up = args[++i];
      else if (args[i] == "--output-units" && more) units_text = args[++i];
      else if (args[i] == "--collision-margin" && more) {
        // read as Python's float() reads it: 1e-400 is 0 (std::stod refused the underflow: usage, exit 2)
        const char* b = args[++i].c_str();
        char* e = nullptr;
        margin = std::strtod(b, &e);
        while (e && (*e == ' ' || *e == '\t')) ++e;
        if (e == b || *e != '\0') throw std::invalid_argument(args[i]);
        margin_given = true;
        // quoted as written, without the blanks around it that strtod reads past (as Node's trim())
        const std::string& a = args[i];
        const auto first = a.find_first_not_of(" \t\n\r\f\v"), last = a.find_last_not_of(" \t\n\r\f\v");
        margin_text = a.substr(first, last - first + 1);
      }
      else if (args[i] == "--check") do_check = true;
      else if (args[i] == "--force") force = true;
      else if (!more && (args[i] == "-o" || (args[i].rfind("--", 0) == 0 &&
                                               std::string(USAGE).find(args[i] + " ") != std::string::npos)))
        throw std::invalid_argument(args[i] + " needs a value");  // a known option given last, with no value
      else pos.push_back(args[i]);
    }
  } catch (const std::exception& e) {
    const std::string what = e.what();
    std::cerr << "error: " << (what.find("needs a value") != std::string::npos ? what : current + " has a bad value")
              << "\n" << USAGE;
    return 2;
  }
  const bool flag_form = !package.empty() || !garment.empty() || !motion.empty();
  // what is wrong, in one line before the usage (the usage alone said nothing of it)
  std::string problem;
  if (!repeated.empty()) problem = repeated + " is given more than once";
  for (const auto& p : pos)
    if (problem.empty() && p.size() > 1 && p[0] == '-') problem = "unknown option " + p;
  if (problem.empty()) {
    if (out.empty()) problem = "-o OUT.pc2 is missing";
    else if (batch < 1) problem = "--batch must be an integer >= 1";
    else if (threads < 1) problem = "--threads must be an integer >= 1";
    else if (up != "y" && up != "z") problem = "--up must be y or z (got " + up + ")";
    else if (!units_text.empty() && !(metres_per_unit(units_text) > 0))
      problem = "--output-units must be m, dm, cm, mm, inch, ft or metres per unit (0.0001..1; centimetres are cm or 0.01), got " + units_text;
    else if (flag_form && package.empty()) problem = "--package is missing";
    else if (flag_form && garment.empty()) problem = "--garment is missing";
    else if (flag_form && motion.empty()) problem = "--motion is missing";
    else if (flag_form && !pos.empty()) problem = "unexpected argument " + pos[0];
    else if (flag_form && do_check) problem = "--check goes with PACKAGE_DIR BUNDLE.sgdb";
    else if (!flag_form && pos.size() != 2) problem = "give PACKAGE_DIR BUNDLE.sgdb, or --package, --garment and --motion";
    else if (!flag_form && (!body_out.empty() || effects_given || margin_given || !cloth.empty() || force))
      problem = "--body-out, --effects, --cloth, --collision-margin and --force go with --package/--garment/--motion";
  }
  if (!problem.empty()) {
    std::cerr << "error: " << problem << "\n" << USAGE;
    return 2;
  }
  // the outputs are claimed before any work, as `segadeform run` claims them (outputs.hpp)
  std::vector<std::string> outputs{out};
  // the body's rest mesh beside its PC2 (what Blender's Mesh Cache and 3ds Max animate), as `segadeform run` writes it
  const std::string rest_obj =
      body_out.empty() ? std::string() : std::filesystem::path(body_out).replace_extension(".obj").string();
  if (!body_out.empty()) {
    outputs.push_back(body_out);
    outputs.push_back(rest_obj);
  }
  const std::vector<std::string> inputs =
      flag_form ? std::vector<std::string>{package, garment, motion} : std::vector<std::string>{pos[0], pos[1]};
  try {
    sgd::claim_outputs(outputs, inputs);
  } catch (const std::exception& e) {
    std::cerr << "Error: " << sgd::outputs_detail::one_line(e.what()) << "\n";
    return 1;
  }
  remove_temporaries_on_signals(outputs);
  try {
    api = OrtGetApiBase()->GetApi(ORT_API_VERSION);
    if (!api) throw std::runtime_error("the onnxruntime library is older than the headers (API " +
                                       std::to_string(ORT_API_VERSION) + ")");
    Package pkg(flag_form ? package : pos[0]);
    sgd::Bundle bundle, asset, mot;
    Scene sc;
    Effects eff;
    sgd::ClothSettings knobs;
    if (flag_form) {
      // the effects first (the package's defaults and --effects): a knob of a stage that will not run, or out of its
      // range, is a command-line mistake, said before the inputs are read, as `segadeform run` says it
      std::string problem;
      try {  // an --effects list's own mistake is a command-line one, exit 2, as `segadeform run` says it (a QA trial)
        eff = !effects_given ? pkg.default_effects() : parse_effects(effects, pkg.default_effects());
      } catch (const std::exception& e) {
        problem = std::string("--effects: ") + e.what();
      }
      if (!problem.empty()) {
      } else if (!cloth.empty() && !eff.cloth) {
        problem = "--cloth sets the cloth stage's knobs, but the stage is off (name cloth in --effects)";
      } else if (!cloth.empty()) {
        try {
          knobs.parse(cloth);
        } catch (const std::exception& e) {
          problem = std::string("--cloth: ") + e.what();
        }
      }
      if (problem.empty() && margin_given && !eff.collisions && !eff.cloth)
        problem = "--collision-margin sets the push-out's margin, but neither collisions nor the cloth stage is on";
      if (problem.empty() && margin_given && !(margin >= 0 && margin < 1))
        problem = "--collision-margin must be in [0, 1) metres (got " + margin_text + ")";
      if (!problem.empty()) {
        std::cerr << "error: " << problem << "\n" << USAGE;
        return 2;
      }
      asset = sgd::read_bundle(garment);
      mot = sgd::read_bundle(motion);
      sc = scene_of_asset(asset, garment, mot, motion, force);
      check_training_body(pkg, force, sc.warnings);
    } else {
      bundle = sgd::read_bundle(pos[1]);
      if (do_check && !bundle.has("expected"))  // said before the sessions are built, naming the file and the fix
        throw std::runtime_error(pos[1] + ": the bundle holds no expected frames to --check against (expected a bundle "
                                 "made without --no-expected, got one made with it)");
      sc = scene_of_bundle(bundle, pos[1]);
      // the scene's post-processes a bundle does not play: its frames are the network's alone (--check included)
      if (bundle.meta.has("left_out") && !bundle.meta["left_out"].arr.empty()) {
        std::string left;
        for (const auto& n : bundle.meta["left_out"].arr) left += (left.empty() ? "" : " and ") + n.str;
        sc.warnings.push_back("the scene's " + left + " are not in the bundle: these frames are the network's alone "
                              "(segadeform garment export and motion export, then --package/--garment/--motion, run them)");
      }
      check_training_body(pkg, false, sc.warnings, "--package/--garment/--motion with --force");
      eff = effects_of(bundle.meta["effects"]);
    }
    for (const auto& w : sc.warnings) std::cerr << "warning: " << w << "\n";
    if (eff.cloth) eff.collisions = false;  // the stage's contact replaces the push-out (as `segadeform run` says)
    StreamOptions so;
    so.effects = eff;
    so.cloth = knobs;
    so.margin = margin;
    so.fps = sc.fps;
    so.batch = batch;
    so.threads = usable_threads(threads);
    if (so.threads < threads)  // more threads than CPUs only contend (1000: about 6 s a frame), as segadeform run says
      std::cout << "threads: " << so.threads << ", not " << threads << " (the CPUs this process may use)\n";
    so.body = !body_out.empty();
    OrtEnv* env;
    check(api->CreateEnv(ORT_LOGGING_LEVEL_WARNING, "segadeform", &env));
    Stream stream(env, pkg, sc, so);
    const int64_t N = sc.N, V = stream.V(), T = sc.T;
    // --check: the bundle's expected frames (the Python runtime's), compared a batch at a time
    const float* expected = nullptr;
    if (do_check) {
      const auto& e = bundle.at("expected");
      if (e.count() != T * N * 3) throw std::runtime_error("the bundle's expected frames have another size than the frames");
      expected = e.as<float>();
    }
    double max_abs = 0, max_ref = 0;
    // the written coordinates' axes and units (--up, --output-units), as `segadeform run` writes them; --check compares
    // the frames as computed
    const bool z_up = up == "z";
    const double unit = units_text.empty() ? 1.0 : metres_per_unit(units_text);
    const bool as_given = !z_up && unit == 1.0;
    // the motion pushed a batch at a time and written as it comes: neither the frames nor the body held whole
    Pc2Writer pc2(out, static_cast<int32_t>(T), static_cast<int32_t>(N), sc.start_frame);
    std::unique_ptr<Pc2Writer> body_pc2;
    if (!body_out.empty()) body_pc2.reset(new Pc2Writer(body_out, static_cast<int32_t>(T), static_cast<int32_t>(V), sc.start_frame));
    // chunks of whole batches, about 256 frames: the frames of one push of the whole motion, in bounded memory
    const int64_t step = batch * std::max<int64_t>(1, 256 / batch);
    std::vector<float> chunk(static_cast<size_t>(step * N * 3)), body(body_pc2 ? static_cast<size_t>(step * V * 3) : 0);
    for (int64_t lo = 0; lo < T; lo += step) {
      const int64_t B = std::min<int64_t>(lo + step, T) - lo;
      stream.push(sc.poses.data() + lo * sc.D, sc.trans.data() + lo * 3, B, chunk.data(), body_pc2 ? body.data() : nullptr);
      if (as_given) {
        pc2.append(chunk.data(), B * N * 3);
        if (body_pc2) body_pc2->append(body.data(), B * V * 3);
      } else {
        pc2.append(to_output<float>(chunk.data(), B * N * 3, z_up, unit).data(), B * N * 3);
        if (body_pc2) body_pc2->append(to_output<float>(body.data(), B * V * 3, z_up, unit).data(), B * V * 3);
      }
      for (int64_t i = 0; expected && i < B * N * 3; ++i) {
        const float x = expected[lo * N * 3 + i];
        max_abs = std::max(max_abs, static_cast<double>(std::fabs(chunk[i] - x)));
        max_ref = std::max(max_ref, static_cast<double>(std::fabs(x)));
      }
    }
    pc2.finish();
    if (body_pc2) {
      body_pc2->finish();
      const std::vector<float> rest = stream.rest_body();
      if (as_given) write_obj(sgd::temporary(rest_obj), rest, stream.body_faces());
      else write_obj(sgd::temporary(rest_obj), to_output<double>(rest.data(), static_cast<int64_t>(rest.size()), z_up, unit),
                     stream.body_faces());
    }
    const sgd::Cloth* stage = stream.cloth();
    if (stage && stage->resets() > 0)
      std::cerr << "cloth: the stage started again from the network's frame at frame " << stage->first_reset()
                << " (the garment jumped)\n";
    sgd::commit_outputs(outputs, inputs);  // all or none
    const double ms = stream.ms_deform() / T, body_ms = stream.ms_body() / T, stage_ms = stream.ms_stage() / T;
    std::printf("%lld frames, %.2f ms/frame (%s%s%s%s%s) -> %s", static_cast<long long>(T), ms,
                eff.skinning.c_str(), eff.dynamics ? ", dynamics" : "", eff.wrinkles ? ", wrinkles" : "",
                eff.collisions ? ", collisions" : "", eff.cloth ? ", cloth" : "", out.c_str());
    if (!body_out.empty())
      std::printf("; body %lld vertices, %.2f ms/frame -> %s", static_cast<long long>(V), body_ms, body_out.c_str());
    if (eff.collisions && !eff.cloth)
      std::printf("; collisions: %lld vertex-frames pushed out (margin %g m), %.2f ms/frame",
                  static_cast<long long>(stream.moved()), margin, stage_ms);
    if (stage)
      std::printf("; cloth: %lld vertex-frames in contact, %lld pushed out after the sweeps, %lld traced out by the "
                  "backstop, %lld reset(s), %.2f ms/frame", static_cast<long long>(stage->contacts()),
                  static_cast<long long>(stage->pushed()), static_cast<long long>(stage->traced()),
                  static_cast<long long>(stage->resets()), stage_ms);
    std::printf("\n");
    if (stream.batch() < batch)  // a big garment: fewer frames a call, as segadeform run says
      std::printf("batch: %d frames a call, not %d (at most %lld vertex-frames a call)\n", stream.batch(), batch,
                  static_cast<long long>(sgd::engine::MAX_VERTEX_FRAMES));
    if (do_check)
      std::printf("PARITY {\"max_abs\": %.9g, \"rel\": %.9g, \"ms_per_frame\": %.3f}\n", max_abs,
                  max_abs / max_ref, ms);
    api->ReleaseEnv(env);
  } catch (const std::exception& e) {
    for (const auto& o : outputs) std::remove(sgd::temporary_name(o).c_str());  // a failed run leaves no output
    remove_temporaries_and_made_folders();  // nor the folders it made for them
    // the engine's refusals of the garment asset name no file: this command names the one it was given
    const std::string what = e.what(), named = flag_form && what.rfind("the garment asset ", 0) == 0 ? garment + ": " : "";
    std::cerr << "Error: " << named << sgd::outputs_detail::one_line(e.what()) << "\n";
    return 1;
  }
  return 0;
}

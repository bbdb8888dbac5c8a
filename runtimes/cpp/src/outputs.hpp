// The output rule of `segadeform run` (src/segadeform/io/output_guard.py) for segadeform-run: no run deletes or
// overwrites a file segadeform did not write.
//
// * claim(): every output is checked before any work.  A new path is written; a file an earlier `run` wrote (the
//   folder's manifest, .segadeform-outputs.json, lists it with its size and modification time, unchanged since) is
//   replaced; anything else -- a file segadeform did not write or that changed since, another command's output, an
//   input of this run, a folder, a second output at the same path, an extension this runtime does not write -- is
//   refused with the reason.
// * commit(): the outputs, already written to hidden temporaries beside them (temporary()), are checked again and
//   renamed into place only once every one is written, so a run that fails leaves none of them; then the manifest
//   records them (the format and kind of Python's `run`: either runtime may replace the other's output).
// POSIX stat (Linux, macOS).
#pragma once
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "json.hpp"

namespace sgd {

namespace outputs_detail {

namespace fs = std::filesystem;
inline const char* MANIFEST = ".segadeform-outputs.json";
inline const char* KIND = "run";
inline const char* NOTE = "files segadeform wrote here (name: command, size, mtime); see segadeform.io.output_guard";

struct Entry {
  std::string kind, size, mtime_ns;  // size and mtime as their digits (mtime_ns ~1.8e18 is past a double's 2^53)
};

struct Manifest {
  std::string folder;  // "folder": kind, when a resumable folder's
  std::map<std::string, Entry> files;
};

// An error is one line (the README's rule): control characters of a file's text shown as \n, \r, \t
inline std::string one_line(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '\n') o += "\\n";
    else if (c == '\r') o += "\\r";
    else if (c == '\t') o += "\\t";
    else o += c;
  }
  return o;
}

inline std::runtime_error refused(const std::string& path, const std::string& problem, const std::string& expected,
                                  const std::string& got) {
  return std::runtime_error(path + ": " + problem + " (expected " + expected + ", got " + one_line(got) + ")");
}

inline std::string parent_of(const std::string& p) {
  fs::path d = fs::path(p).parent_path();
  return d.empty() ? "." : d.string();
}

inline std::string name_of(const std::string& p) { return fs::path(p).filename().string(); }

// "mtime_ns": 123 -> "mtime_ns": "123" (and "size" alike), so that the reader keeps every digit
inline std::string quote_numbers(const std::string& text) {
  std::string out;
  out.reserve(text.size() + 64);
  size_t i = 0;
  while (i < text.size()) {
    bool done = false;
    for (const char* key : {"\"mtime_ns\"", "\"size\""}) {
      const std::string k(key);
      if (text.compare(i, k.size(), k) == 0) {
        size_t j = i + k.size();
        while (j < text.size() && std::isspace(static_cast<unsigned char>(text[j]))) ++j;
        if (j < text.size() && text[j] == ':') {
          ++j;
          while (j < text.size() && std::isspace(static_cast<unsigned char>(text[j]))) ++j;
          size_t e = j;
          while (e < text.size() && std::isdigit(static_cast<unsigned char>(text[e]))) ++e;
          if (e > j) {
            out += k + ": \"" + text.substr(j, e - j) + "\"";
            i = e;
            done = true;
          }
        }
        break;
      }
    }
    if (!done) out += text[i++];
  }
  return out;
}

inline Manifest read_manifest(const std::string& folder) {
  const std::string p = (fs::path(folder) / MANIFEST).string();
  std::ifstream f(p, std::ios::binary);
  Manifest m;
  if (!f) return m;  // none (or a folder that does not exist yet)
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string text = ss.str();
  const auto bad = [&]() {
    return refused(p, "not a segadeform outputs manifest, and segadeform does not overwrite it",
                   "JSON with \"segadeform_outputs\": 1", "'" + text.substr(0, 40) + "'");
  };
  Json j;
  try {
    j = parse_json(quote_numbers(text));
  } catch (const std::exception&) {
    throw bad();
  }
  if (j.kind != Json::Object || !j.has("segadeform_outputs") || j["segadeform_outputs"].kind != Json::Number ||
      j["segadeform_outputs"].num != 1 || !j.has("files") || j["files"].kind != Json::Object)
    throw bad();
  if (j.has("folder") && j["folder"].kind == Json::String) m.folder = j["folder"].str;
  for (const auto& [name, e] : j["files"].obj) {
    if (e.kind != Json::Object || !e.has("kind") || e["kind"].kind != Json::String) throw bad();
    Entry x;
    x.kind = e["kind"].str;
    if (e.has("size") && e["size"].kind == Json::String) x.size = e["size"].str;
    if (e.has("mtime_ns") && e["mtime_ns"].kind == Json::String) x.mtime_ns = e["mtime_ns"].str;
    m.files[name] = x;
  }
  return m;
}

inline std::string json_string(const std::string& s) {
  std::string o = "\"";
  for (unsigned char c : s) {
    if (c == '"' || c == '\\') {
      o += '\\';
      o += static_cast<char>(c);
    } else if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      o += buf;
    } else {
      o += static_cast<char>(c);
    }
  }
  return o + "\"";
}

inline bool lstat_of(const std::string& p, struct stat* st) { return ::lstat(p.c_str(), st) == 0; }

inline std::string mtime_ns(const struct stat& st) {
#if defined(__APPLE__)
  const auto& t = st.st_mtimespec;
#else
  const auto& t = st.st_mtim;
#endif
  return std::to_string(static_cast<unsigned long long>(t.tv_sec) * 1000000000ULL +
                        static_cast<unsigned long long>(t.tv_nsec));
}

inline bool same_file(const std::string& a, const std::string& b) {
  struct stat sa, sb;
  if (::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
  std::error_code ec;
  return fs::weakly_canonical(a, ec) == fs::weakly_canonical(b, ec);
}

inline bool inside(const std::string& p, const std::string& folder) {
  std::error_code ec;
  const std::string a = fs::weakly_canonical(p, ec).string(), f = fs::weakly_canonical(folder, ec).string();
  return !f.empty() && a.size() > f.size() && a.compare(0, f.size(), f) == 0 && a[f.size()] == '/';
}

}  // namespace outputs_detail

/** Check every output of this run before any work (see the file's comment); throws std::runtime_error saying why. */
inline void claim_outputs(const std::vector<std::string>& outputs, const std::vector<std::string>& inputs) {
  using namespace outputs_detail;
  std::vector<std::string> seen;
  const auto ext_of = [](const std::string& p) {
    std::string ext = fs::path(p).extension().string();
    for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return ext;
  };
  for (const std::string& out : outputs) {
    const std::string ext = ext_of(out);
    // the body's rest mesh (.obj) beside a body PC2 of the same run, as `segadeform run` writes it
    bool rest_mesh = false;
    for (const std::string& o : outputs)
      rest_mesh = rest_mesh || (ext == ".obj" && ext_of(o) == ".pc2" &&
                                fs::path(o).replace_extension(".obj").lexically_normal() ==
                                    fs::path(out).lexically_normal());
    if (ext != ".pc2" && !rest_mesh)
      throw refused(out, "this runtime writes PC2 point caches only", ".pc2", ext.empty() ? "none" : ext);
    for (const std::string& s : seen)
      if (same_file(s, out))
        throw refused(out, "two outputs of this run would be written to this one path", "one path per output", out);
    seen.push_back(out);
    std::error_code ec;
    for (fs::path a = fs::absolute(out, ec).parent_path(); !a.empty() && a != a.parent_path(); a = a.parent_path()) {
      struct stat sa;
      if (::stat(a.c_str(), &sa) == 0 && !S_ISDIR(sa.st_mode))
        throw refused(out, "is a path inside a file", "a path in a folder", a.string() + " (a file)");
    }
    for (const std::string& in : inputs)
      if (!in.empty() && (same_file(out, in) || inside(out, in)))
        throw refused(out, "is an input of this run, and a run never writes over its inputs",
                      "an output path that is not an input", in);
    const Manifest m = read_manifest(parent_of(out));  // a manifest that is not one is refused before any work
    struct stat st;
    if (!lstat_of(out, &st)) continue;
    if (S_ISDIR(st.st_mode)) throw refused(out, "is a folder", "a file path for this output", "a folder");
    auto it = m.files.find(name_of(out));
    const bool same = it != m.files.end() && S_ISREG(st.st_mode) && it->second.size == std::to_string(st.st_size) &&
                      it->second.mtime_ns == mtime_ns(st);
    if (!same)
      throw refused(out,
                    std::string("exists and ") +
                        (it == m.files.end() ? "segadeform did not write it" : "it changed since segadeform wrote it (its size or modification time: edited, or touched)") +
                        "; segadeform never overwrites such a file",
                    "a new path, or remove the file yourself", "an existing file");
    if (it->second.kind != KIND)
      throw refused(out, "exists, written by `segadeform " + it->second.kind +
                             "`; a run does not replace another command's output",
                    "another path", "an output of segadeform " + it->second.kind);
  }
}

/** The name of the hidden temporary an output is written to before commit_outputs. */
inline std::string temporary_name(const std::string& out) {
  using namespace outputs_detail;
  return (fs::path(parent_of(out)) / ("." + name_of(out) + ".tmp-" + std::to_string(::getpid()))).string();
}

/** The hidden temporary an output is written to before commit_outputs, its folder made when missing. */
inline std::string temporary(const std::string& out) {
  outputs_detail::fs::create_directories(outputs_detail::parent_of(out));
  return temporary_name(out);
}

/** Rename every output's temporary into place (after checking the claims again) and record them in the folders'
 * manifests; on a refusal the temporaries are removed and nothing is replaced. */
inline void commit_outputs(const std::vector<std::string>& outputs, const std::vector<std::string>& inputs) {
  using namespace outputs_detail;
  try {
    claim_outputs(outputs, inputs);
  } catch (...) {
    for (const auto& o : outputs) std::remove(temporary_name(o).c_str());
    throw;
  }
  std::map<std::string, std::map<std::string, Entry>> added;
  for (const auto& o : outputs) {
    const std::string tmp = temporary_name(o);
    if (std::rename(tmp.c_str(), o.c_str()) != 0) {
      std::remove(tmp.c_str());
      throw std::runtime_error(o + ": cannot rename its temporary into place");
    }
    struct stat st;
    if (!lstat_of(o, &st)) throw std::runtime_error(o + ": missing after it was written");
    added[parent_of(o)][name_of(o)] = Entry{KIND, std::to_string(st.st_size), mtime_ns(st)};
  }
  for (const auto& [folder, add] : added) {
    Manifest m = read_manifest(folder);
    for (const auto& [n, e] : add) m.files[n] = e;
    std::string text = "{\n \"segadeform_outputs\": 1,\n \"note\": " + json_string(NOTE) + ",\n";
    if (!m.folder.empty()) text += " \"folder\": " + json_string(m.folder) + ",\n";
    text += " \"files\": {";
    bool first = true;
    for (const auto& [n, e] : m.files) {  // std::map: sorted by name, as Python writes them
      text += std::string(first ? "\n" : ",\n") + "  " + json_string(n) + ": {\n   \"kind\": " + json_string(e.kind);
      if (!e.size.empty()) text += ",\n   \"size\": " + e.size;
      if (!e.mtime_ns.empty()) text += ",\n   \"mtime_ns\": " + e.mtime_ns;
      text += "\n  }";
      first = false;
    }
    text += first ? "}\n}\n" : "\n }\n}\n";
    const std::string p = (fs::path(folder) / MANIFEST).string();
    const std::string tmp = (fs::path(folder) / ("." + std::string(MANIFEST) + ".tmp-" + std::to_string(::getpid())))
                                .string();
    {
      std::ofstream f(tmp, std::ios::binary);
      f << text;
      if (!f) throw std::runtime_error(p + ": cannot write the outputs manifest");
    }
    if (std::rename(tmp.c_str(), p.c_str()) != 0) {
      std::remove(tmp.c_str());
      throw std::runtime_error(p + ": cannot write the outputs manifest");
    }
  }
}

// The command lines' arguments with --name=value read as --name value (as click reads `segadeform run
// --effects=+cloth`): segadeform-run's and segadeform-play's.
inline std::vector<std::string> command_args(int argc, char** argv) {
  std::vector<std::string> args;
  for (int k = 1; k < argc; ++k) {
    const std::string a = argv[k];
    const size_t eq = a.find('=');
    if (a.rfind("--", 0) == 0 && eq != std::string::npos) {
      args.push_back(a.substr(0, eq));
      args.push_back(a.substr(eq + 1));
    } else {
      args.push_back(a);
    }
  }
  return args;
}

}  // namespace sgd

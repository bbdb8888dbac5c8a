// A small JSON reader for manifests and bundle metadata (objects, arrays, strings, numbers, literals).
#pragma once
#include <cstdlib>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace sgd {

struct Json {
  enum Kind { Null, Bool, Number, String, Array, Object } kind = Null;
  bool b = false;
  double num = 0.0;
  std::string str;
  std::vector<Json> arr;
  std::map<std::string, Json> obj;

  const Json& operator[](const std::string& k) const {
    auto it = obj.find(k);
    if (kind != Object || it == obj.end()) throw std::runtime_error("JSON: no key '" + k + "'");
    return it->second;
  }
  bool has(const std::string& k) const { return kind == Object && obj.count(k); }
};

class JsonParser {
 public:
  explicit JsonParser(const std::string& s) : s_(s) {}
  Json parse() {
    Json v = value(0);
    ws();
    if (i_ != s_.size()) fail("trailing characters");
    return v;
  }

 private:
  static constexpr int MAX_DEPTH = 256;  // nesting deeper than any file here has (a crafted one overflowed the stack)
  const std::string& s_;
  size_t i_ = 0;
  [[noreturn]] void fail(const std::string& what) {
    throw std::runtime_error("JSON: " + what + " at offset " + std::to_string(i_));
  }
  char peek() const { return i_ < s_.size() ? s_[i_] : '\0'; }  // '\0' at the end: never read past it
  void ws() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\n' || s_[i_] == '\r' || s_[i_] == '\t')) ++i_;
  }
  bool lit(const char* w) {
    size_t n = std::string(w).size();
    if (s_.compare(i_, n, w) == 0) { i_ += n; return true; }
    return false;
  }
  Json value(int depth) {
    ws();
    if (i_ >= s_.size()) fail("unexpected end");
    if (depth > MAX_DEPTH) fail("nested deeper than " + std::to_string(MAX_DEPTH));
    Json v;
    char c = s_[i_];
    if (c == '{') {
      v.kind = Json::Object; ++i_; ws();
      if (peek() == '}') { ++i_; return v; }
      for (;;) {
        ws();
        Json k = value(depth + 1);
        if (k.kind != Json::String) fail("object key must be a string");
        ws();
        if (peek() != ':') fail("expected ':'");
        ++i_;
        v.obj[k.str] = value(depth + 1);
        ws();
        if (peek() == ',') { ++i_; continue; }
        if (peek() == '}') { ++i_; return v; }
        fail("expected ',' or '}'");
      }
    }
    if (c == '[') {
      v.kind = Json::Array; ++i_; ws();
      if (peek() == ']') { ++i_; return v; }
      for (;;) {
        v.arr.push_back(value(depth + 1));
        ws();
        if (peek() == ',') { ++i_; continue; }
        if (peek() == ']') { ++i_; return v; }
        fail("expected ',' or ']'");
      }
    }
    if (c == '"') {
      v.kind = Json::String; ++i_;
      while (i_ < s_.size() && s_[i_] != '"') {
        if (s_[i_] == '\\') {
          ++i_;
          char e = peek();
          if (e == 'n') v.str += '\n'; else if (e == 't') v.str += '\t';
          else if (e == 'u') { v.str += '?'; i_ += 4; }  // names here are ASCII
          else v.str += e;
          ++i_;
        } else {
          v.str += s_[i_++];
        }
      }
      if (i_ >= s_.size()) fail("unterminated string");
      ++i_;
      return v;
    }
    if (lit("true")) { v.kind = Json::Bool; v.b = true; return v; }
    if (lit("false")) { v.kind = Json::Bool; v.b = false; return v; }
    if (lit("null")) return v;
    const char* start = s_.c_str() + i_;
    char* end = nullptr;
    v.num = std::strtod(start, &end);
    if (end == start) fail("unexpected character");
    v.kind = Json::Number;
    i_ += static_cast<size_t>(end - start);
    return v;
  }
};

inline Json parse_json(const std::string& s) { return JsonParser(s).parse(); }

}  // namespace sgd

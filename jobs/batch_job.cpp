#include "jobs/batch_job.h"

#include <algorithm>
#include <cctype>
#include <limits>
#include <sstream>
#include <map>
#include <set>
#include <string>
#include <string_view>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <toml++/toml.h>

#include "io/atomic_file.h"
#include "io/input_file.h"
#include "io/printable.h"
#include "jobs/batch_run.h"
#include "kernels/core/errors.h"

namespace gimforge::jobs {
namespace {

bool is_mesh_file(const std::filesystem::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".ply" || ext == ".obj" || ext == ".off" || ext == ".stl";
}

std::string label_for(const CollectionSpec& c, const std::filesystem::path& relative) {
  switch (c.label_rule) {
    case LabelRule::None: return {};
    case LabelRule::Fixed: return c.label;
    case LabelRule::Folder: {
      const std::filesystem::path parent = relative.parent_path();
      return parent.empty() ? std::string() : parent.filename().generic_string();
    }
  }
  return {};
}

void from_directory(const CollectionSpec& c, std::vector<CollectionItem>& out) {
  std::error_code ec;
  if (!std::filesystem::is_directory(c.input, ec))
    throw IoError(fmt::format("{}: not a directory (--input)", c.input.string()));
  std::vector<std::filesystem::path> found;
  for (auto it = std::filesystem::recursive_directory_iterator(c.input, ec);
       !ec && it != std::filesystem::recursive_directory_iterator(); it.increment(ec))
    if (is_mesh_file(it->path())) {
      std::error_code type;
      if (it->is_regular_file(type))
        found.push_back(it->path());
      else if (!it->is_directory(type))  // said, not silently left out of the collection
        spdlog::warn("{}: skipped: not a regular file (a dangling link, a pipe or a device)",
                     io::printable(it->path().string()));
    }
  if (ec) throw IoError(fmt::format("{}: cannot list: {}", c.input.string(), ec.message()));
  for (const std::filesystem::path& p : found) {
    const std::filesystem::path rel = std::filesystem::relative(p, c.input);
    out.push_back({c.prefix + std::filesystem::path(rel).replace_extension().generic_string(), p.string(),
                   label_for(c, rel)});
  }
}

/// Largest list or job file read (a list of a million long paths fits).
constexpr std::size_t kMaxTextInputBytes = std::size_t{256} << 20;

void from_list(const CollectionSpec& c, std::vector<CollectionItem>& out) {
  std::istringstream in(io::read_text_input(c.list, kMaxTextInputBytes));  // a pipe too: --list <(find ...)
  // Relative paths are relative to the list's folder; a pipe's folder (/dev/fd) means nothing: the current one.
  std::error_code ec;
  const std::filesystem::path base = std::filesystem::is_regular_file(c.list, ec) ? c.list.parent_path() : "";
  const std::size_t before = out.size();
  std::string line;
  for (std::size_t number = 1; std::getline(in, line); ++number) {
    if (number == 1 && line.starts_with("\xEF\xBB\xBF")) line.erase(0, 3);  // a UTF-8 byte-order mark
    if (line.find('\0') != std::string::npos) {  // no path holds one: C strings would cut it there
      spdlog::warn("{}:{}: skipped: the line holds a NUL byte", io::printable(c.list.string()), number);
      continue;
    }
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.pop_back();
    const std::size_t start = line.find_first_not_of(" \t");
    if (start == std::string::npos || line[start] == '#') continue;
    std::filesystem::path p = line.substr(start);
    if (p.is_relative()) p = base / p;
    const std::filesystem::path rel = p.filename();
    CollectionItem item{c.prefix + p.stem().generic_string(), p.lexically_normal().string(), {}};
    // The folder that holds the file, not the line's last directory part ("../a.ply" is not of class "..").
    item.label = c.label_rule == LabelRule::Folder
                     ? std::filesystem::absolute(p).lexically_normal().parent_path().filename().generic_string()
                     : label_for(c, rel);
    out.push_back(std::move(item));
  }
  if (out.size() == before) throw InvalidInput(fmt::format("{}: the list names no mesh", c.list.string()));
}

[[noreturn]] void toml_error(const std::filesystem::path& path, const toml::source_region& where, const std::string& what) {
  throw FormatError(fmt::format("{}:{}: {}", path.string(), where.begin.line, what));
}

/// Where key `key` of `t` is written (its value), or the table's header when it is absent.
const toml::source_region& source_of(const toml::table& t, std::string_view key) {
  const toml::node* node = t.get(key);
  return node != nullptr ? node->source() : t.source();
}

template <class T>
T value_or(const toml::table& t, std::string_view key, T fallback, const std::filesystem::path& path) {
  const toml::node* node = t.get(key);
  if (!node) return fallback;
  if constexpr (std::is_same_v<T, std::string>) {
    if (const auto v = node->value<std::string>()) return *v;
    toml_error(path, node->source(), fmt::format("'{}' must be a string", key));
  } else if constexpr (std::is_same_v<T, bool>) {
    if (const auto v = node->value_exact<bool>()) return *v;
    toml_error(path, node->source(), fmt::format("'{}' must be true or false", key));
  } else if constexpr (std::is_floating_point_v<T>) {
    if (const auto v = node->value<double>()) return *v;  // integers convert too
    toml_error(path, node->source(), fmt::format("'{}' must be a number", key));
  } else {
    if (const auto v = node->value_exact<std::int64_t>(); v && *v >= 0 &&
                                                          static_cast<std::uint64_t>(*v) <= std::numeric_limits<T>::max())
      return static_cast<T>(*v);
    toml_error(path, node->source(),
               fmt::format("'{}' must be an integer in 0..{}", key, std::numeric_limits<T>::max()));
  }
}

void check_keys(const toml::table& t, const std::set<std::string_view>& allowed, const std::filesystem::path& path,
                std::string_view where) {
  for (const auto& [key, node] : t)
    if (!allowed.contains(key.str()))
      toml_error(path, node.source(), fmt::format("unknown key '{}' in {}", key.str(), where));
}

/// A message of the shared option checks in a job file's words: `--roi-gain 100` becomes `roi_gain 100` (every
/// option of an [[output]] is the key of the same name, dashes as underscores).
std::string in_job_words(std::string_view message) {
  std::string out;
  for (std::size_t i = 0; i < message.size(); ++i) {
    const bool option = message.substr(i, 2) == "--" && i + 2 < message.size() && std::islower(static_cast<unsigned char>(message[i + 2])) &&
                        (i == 0 || message[i - 1] == ' ' || message[i - 1] == '(' || message[i - 1] == '\'');
    if (!option) {
      out.push_back(message[i]);
      continue;
    }
    for (i += 2; i < message.size() && (std::islower(static_cast<unsigned char>(message[i])) || message[i] == '-'); ++i)
      out.push_back(message[i] == '-' ? '_' : message[i]);
    --i;
  }
  return out;
}

}  // namespace

void OutputSpec::check() const {
  // The name becomes a path component (the shards' directory, /batch/<name>) and is printed.
  if (const std::string problem = io::path_component_problem(name); !problem.empty())
    throw InvalidInput(fmt::format("output '{}': the name {} (it must be one file-name component: non-empty, not "
                                   "'.' or '..', no '/' and no control characters, at most 255 bytes)",
                                   io::printable(name), problem));
  method.check(fmt::format("output '{}'", name));
  if (method.method == Method::Gim && method.size > kMaxGimSize)
    throw InvalidInput(fmt::format("output '{}': gim size {} is too large (at most {})", name, method.size, kMaxGimSize));
}

std::vector<io::ItemKey> BatchJob::keys() const {
  std::vector<io::ItemKey> out;
  for (const OutputSpec& o : outputs)
    for (std::size_t i = 0; i < items.size(); ++i) out.push_back({o.name, items[i].name, items[i].source, items[i].label, i});
  return out;
}

namespace {

/// Why `prefix` cannot start item names, or empty: it starts every item name, whose parts `--name
/// batch/OUTPUT/ITEM` reads back, so it is names (file-name components) joined by '/', a final '/' allowed.
std::string prefix_problem(std::string_view prefix) {
  for (std::size_t start = 0; start < prefix.size();) {
    const std::size_t end = std::min(prefix.find('/', start), prefix.size());
    if (const std::string problem = io::path_component_problem(prefix.substr(start, end - start)); !problem.empty())
      return fmt::format("must be names joined by '/' (as \"train/\"): its part '{}' {}",
                         io::printable(prefix.substr(start, end - start)), problem);
    start = end + 1;
  }
  return {};
}

}  // namespace

std::vector<CollectionItem> discover(const std::vector<CollectionSpec>& collections) {
  std::vector<CollectionItem> items;
  for (const CollectionSpec& c : collections) {
    // What every item of the collection shares, checked once with its own message (below, per file).
    for (const auto& [what, text] : {std::pair<std::string_view, std::string>{"--input", c.input.string()},
                                     {"--list", c.list.string()}, {"the label", c.label}, {"the prefix", c.prefix}})
      if (!io::valid_utf8(text))
        throw InvalidInput(fmt::format("{} '{}' is not valid UTF-8, which item names, the journal and the archive's "
                                       "strings cannot hold",
                                       what, io::printable(text)));
    // Labels and prefixes end up in item names, archives and log lines (the job file says where, above).
    for (const auto& [what, text] : {std::pair<std::string_view, const std::string&>{"the label", c.label},
                                     {"the prefix", c.prefix}})
      if (io::has_unprintable(text))
        throw InvalidInput(fmt::format("{} '{}' contains a control character", what, io::printable(text)));
    if (const std::string problem = prefix_problem(c.prefix); !problem.empty())
      throw InvalidInput(fmt::format("the prefix '{}' {}", io::printable(c.prefix), problem));
    if (!c.input.empty()) from_directory(c, items);
    if (!c.list.empty()) from_list(c, items);
  }
  // Names, paths and labels go into JSON (the journal, the job's identity) and the archive's UTF-8 strings:
  // a file whose path is not valid UTF-8 is said and left out, like a dangling link, instead of failing the job.
  std::erase_if(items, [](const CollectionItem& item) {
    if (io::valid_utf8(item.name) && io::valid_utf8(item.source) && io::valid_utf8(item.label)) return false;
    spdlog::warn("{}: skipped: its path is not valid UTF-8 (rename the file or its folder{})", io::printable(item.source),
                 io::valid_utf8(item.label) ? "" : ", which labels it");
    return true;
  });
  std::sort(items.begin(), items.end(), [](const CollectionItem& a, const CollectionItem& b) { return a.source < b.source; });
  if (items.empty()) {
    std::vector<std::string> where;
    for (const CollectionSpec& c : collections) {
      if (!c.input.empty()) where.push_back(io::printable(c.input.string()));
      if (!c.list.empty()) where.push_back(io::printable(c.list.string()));
    }
    throw InvalidInput(fmt::format("the collection has no meshes (.ply .obj .off .stl) in {}", fmt::join(where, ", ")));
  }
  std::map<std::string, const CollectionItem*> names;
  for (const CollectionItem& item : items)
    if (auto [it, inserted] = names.emplace(item.name, &item); !inserted)
      throw InvalidInput(fmt::format("two meshes would get the item name '{}': {} and {} (use a directory input, "
                                     "or a prefix per collection)",
                                     item.name, it->second->source, item.source));
  return items;
}

BatchJob make_job(const BatchOptions& o) {
  if (!o.job.empty()) {
    if (!o.input.empty() || !o.list.empty())
      throw InvalidInput("--job describes the collection: do not combine it with --input or --list");
    if (!o.method.codec.empty() || o.method.rate != 0)
      throw InvalidInput("--codec and --rate describe the single output of --input or --list; with --job set codec and "
                         "rate in its [[output]] tables");
    BatchJob job = load_job_file(o.job);
    if (o.metric_samples_set) job.metric_samples = o.metric_samples;
    if (o.no_metric) job.metric = false;
    return job;
  }
  if (o.input.empty() == o.list.empty()) throw InvalidInput("give exactly one of --input DIR, --list FILE or --job JOB.toml");
  CollectionSpec c;
  c.input = o.input;
  c.list = o.list;
  c.label_rule = o.label == "folder" ? LabelRule::Folder : o.label == "none" ? LabelRule::None : LabelRule::Fixed;
  if (c.label_rule == LabelRule::Fixed) c.label = o.label;
  BatchJob job;
  job.items = discover({c});
  OutputSpec out;
  out.method = o.method;
  out.method.normal_size = 0;  // batch items keep positions only
  out.name = out.method.default_output_name();
  out.check();
  job.outputs.push_back(out);
  job.metric_samples = o.metric_samples;
  job.metric = !o.no_metric;
  return job;
}

BatchJob load_job_file(const std::filesystem::path& path) {
  toml::table root;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError(fmt::format("{}: no such job file", path.string()));
  try {
    root = toml::parse(io::read_text_input(path, kMaxTextInputBytes), path.string());
  } catch (const toml::parse_error& e) {
    toml_error(path, e.source(), std::string(e.description()));
  }
  check_keys(root, {"metric_samples", "metric", "collection", "output"}, path, "the job file");
  const std::filesystem::path base = path.parent_path();
  auto resolve = [&](const std::string& p) { return std::filesystem::path(p).is_relative() ? base / p : std::filesystem::path(p); };
  BatchJob job;
  job.metric_samples = value_or<std::size_t>(root, "metric_samples", job.metric_samples, path);
  if (job.metric_samples < 1 || job.metric_samples > kMaxMetricSamples)
    throw FormatError(fmt::format("{}: metric_samples = {} is outside 1..{}", path.string(), job.metric_samples,
                                  kMaxMetricSamples));
  if (const toml::node* metric = root.get("metric")) {
    const auto v = metric->value<bool>();
    if (!v) toml_error(path, metric->source(), "'metric' must be true or false");
    job.metric = *v;
  }

  std::vector<CollectionSpec> collections;
  const toml::array* cs = root["collection"].as_array();
  if (!cs || cs->empty()) throw FormatError(fmt::format("{}: no [[collection]] table", path.string()));
  for (const toml::node& node : *cs) {
    const toml::table* t = node.as_table();
    if (!t) toml_error(path, node.source(), "[[collection]] must be a table");
    check_keys(*t, {"input", "list", "label", "prefix"}, path, "[[collection]]");
    CollectionSpec c;
    const std::string input = value_or<std::string>(*t, "input", "", path);
    const std::string list = value_or<std::string>(*t, "list", "", path);
    if (input.empty() == list.empty()) toml_error(path, t->source(), "a [[collection]] needs exactly one of 'input' and 'list'");
    if (!input.empty()) c.input = resolve(input);
    if (!list.empty()) c.list = resolve(list);
    const std::string label = value_or<std::string>(*t, "label", "folder", path);
    c.label_rule = label == "folder" ? LabelRule::Folder : label == "none" ? LabelRule::None : LabelRule::Fixed;
    if (c.label_rule == LabelRule::Fixed) c.label = label;
    c.prefix = value_or<std::string>(*t, "prefix", "", path);
    // Labels and prefixes end up in item names, archives and log lines.
    for (const auto& [key, value] : {std::pair<const char*, const std::string&>{"label", c.label}, {"prefix", c.prefix}})
      if (io::has_unprintable(value))
        toml_error(path, source_of(*t, key),
                   fmt::format("{} '{}' contains a control character or invalid UTF-8", key, io::printable(value)));
    if (const std::string problem = prefix_problem(c.prefix); !problem.empty())
      toml_error(path, source_of(*t, "prefix"), fmt::format("prefix '{}' {}", io::printable(c.prefix), problem));
    collections.push_back(std::move(c));
  }
  const toml::array* os = root["output"].as_array();
  if (!os || os->empty()) throw FormatError(fmt::format("{}: no [[output]] table", path.string()));
  std::set<std::string> names;
  for (const toml::node& node : *os) {
    const toml::table* t = node.as_table();
    if (!t) toml_error(path, node.source(), "[[output]] must be a table");
    check_keys(*t, {"method", "name", "size", "max_augmentations", "domain", "n", "grid", "texture", "max_grid",
                    "occlusion_threshold", "samples", "charts", "optimize", "proxy_faces", "proxy_bricks", "wrap", "sampling",
                    "adapt_rounds", "adapt_start", "roi", "roi_gain", "codec", "rate"},
               path, "[[output]]");
    OutputSpec o;
    MethodOptions& m = o.method;
    try {
      m.method = parse_method(value_or<std::string>(*t, "method", std::string(method_name(m.method)), path));
    } catch (const InvalidInput& e) {
      toml_error(path, t->source(), e.what());
    }
    // Another method's keys are refused, as the command line refuses another method's options.
    const std::map<std::string_view, Method> owner{{"size", Method::Gim},          {"max_augmentations", Method::Gim},
                                                   {"domain", Method::Sphere},     {"n", Method::Sphere},
                                                   {"grid", Method::Relief},       {"texture", Method::Relief},
                                                   {"max_grid", Method::Relief},   {"occlusion_threshold", Method::Relief},
                                                   {"samples", Method::Mcgim},     {"charts", Method::Mcgim}};
    for (const auto& [key, value] : *t)
      if (const auto it = owner.find(key.str()); it != owner.end() && it->second != m.method)
        toml_error(path, value.source(), fmt::format("'{}' applies to method \"{}\" only (this output is \"{}\")",
                                                    key.str(), method_name(it->second), method_name(m.method)));
    m.size = value_or<std::uint32_t>(*t, "size", m.size, path);
    m.max_augmentations = value_or<int>(*t, "max_augmentations", m.max_augmentations, path);
    m.sampling = value_or<std::string>(*t, "sampling", m.sampling, path);
    m.adapt_rounds = value_or<std::uint32_t>(*t, "adapt_rounds", m.adapt_rounds, path);
    m.adapt_start = value_or<std::string>(*t, "adapt_start", m.adapt_start, path);
    m.roi = value_or<std::string>(*t, "roi", m.roi, path);
    // A file of vertex indices or a mask, like every path of the job file, from the file's folder.
    for (const std::string kind : {"vertices:", "mask:"})
      if (m.roi.starts_with(kind) && m.roi.size() > kind.size())
        m.roi = kind + resolve(m.roi.substr(kind.size())).string();
    m.roi_gain = value_or<double>(*t, "roi_gain", m.roi_gain, path);
    for (const char* key : {"sampling", "adapt_rounds", "adapt_start", "roi", "roi_gain"})
      if (const toml::node* value = t->get(key); value != nullptr && m.method != Method::Gim && m.method != Method::Sphere)
        toml_error(path, value->source(), fmt::format("'{}' applies to methods \"gim\" and \"sphere\" only (this output "
                                                      "is \"{}\")",
                                                      key, method_name(m.method)));
    for (const char* key : {"adapt_rounds", "adapt_start", "roi", "roi_gain"})
      if (const toml::node* value = t->get(key); value != nullptr && !m.adaptive())
        toml_error(path, value->source(), fmt::format("'{}' applies to sampling \"adaptive\" only", key));
    if (const toml::node* value = t->get("roi_gain"); value != nullptr && m.roi.empty())
      toml_error(path, value->source(), "'roi_gain' applies with 'roi' only");
    m.domain = value_or<std::string>(*t, "domain", m.domain, path);
    m.n = value_or<std::uint32_t>(*t, "n", m.n, path);
    m.codec = value_or<std::string>(*t, "codec", m.codec, path);
    m.rate = value_or<std::uint64_t>(*t, "rate", m.rate, path);
    // "auto" or a count, as a string (MethodOptions checks it): grid, charts.
    const auto auto_or_count = [&](const char* key, std::string& field, std::string_view what) {
      if (const toml::node* value = t->get(key); value && !value->is_string()) {
        if (!value->is_integer())
          toml_error(path, value->source(), fmt::format("'{}' must be \"auto\" or a number of {}", key, what));
        field = std::to_string(value_or<std::uint32_t>(*t, key, 0, path));
      } else {
        field = value_or<std::string>(*t, key, field, path);
      }
    };
    auto_or_count("grid", m.grid, "cells per axis");
    if ((t->get("max_grid") != nullptr || t->get("occlusion_threshold") != nullptr) && m.grid != "auto")
      toml_error(path, t->source(), fmt::format("'max_grid' and 'occlusion_threshold' apply to grid \"auto\" only "
                                                "(this output has grid {})",
                                                m.grid));
    m.texture = value_or<std::uint32_t>(*t, "texture", m.texture, path);
    m.max_grid = value_or<std::uint32_t>(*t, "max_grid", m.max_grid, path);
    m.occlusion_threshold = value_or<double>(*t, "occlusion_threshold", m.occlusion_threshold, path);
    m.samples = value_or<std::uint32_t>(*t, "samples", m.samples, path);
    auto_or_count("charts", m.charts, "charts");
    m.optimize = value_or<bool>(*t, "optimize", m.optimize, path);
    // "auto", "off" or a face count (a string or an integer).
    if (const toml::node* value = t->get("proxy_faces"); value && value->is_integer())
      m.proxy_faces = std::to_string(value_or<std::uint32_t>(*t, "proxy_faces", 0, path));
    else
      m.proxy_faces = value_or<std::string>(*t, "proxy_faces", m.proxy_faces, path);
    m.proxy_bricks = value_or<std::uint32_t>(*t, "proxy_bricks", m.proxy_bricks, path);
    // "off", "R" or "R:C" (a string), or R (an integer; its range is checked with the string's).
    if (const toml::node* value = t->get("wrap"); value && value->is_integer())
      m.wrap = std::to_string(value->as_integer()->get());
    else if (value && !value->is_string())
      toml_error(path, value->source(), "'wrap' must be \"off\", \"R\" or \"R:C\" (a string), or an integer R");
    else
      m.wrap = value_or<std::string>(*t, "wrap", m.wrap, path);
    m.normal_size = 0;  // batch items keep positions only
    o.name = value_or<std::string>(*t, "name", m.default_output_name(), path);
    try {
      o.check();
    } catch (const InvalidInput& e) {
      // At the key the message is about ("output 'gim_66': gim size 66 ..." is about 'size'), when it names
      // one: the longest key it names, its '_' read as a space ("normal size" is 'normal_size', not 'size').
      const toml::source_region* at = &t->source();
      std::size_t longest = 0;
      const std::string words = in_job_words(e.what());
      for (const auto& [key, value] : *t) {
        std::string spaced(key.str());
        std::replace(spaced.begin(), spaced.end(), '_', ' ');
        if (spaced.size() > longest && (words.find(" " + spaced + " ") != std::string::npos ||
                                        words.find("'" + std::string(key.str()) + "'") != std::string::npos)) {
          at = &value.source();
          longest = spaced.size();
        }
      }
      toml_error(path, *at, words);
    }
    if (!names.insert(o.name).second) toml_error(path, source_of(*t, "name"), fmt::format("two outputs are named '{}'", o.name));
    job.outputs.push_back(std::move(o));
  }
  job.items = discover(collections);
  return job;
}

nlohmann::json output_json(const OutputSpec& o) {
  const MethodOptions& m = o.method;
  nlohmann::json j = {{"name", o.name},       {"method", method_name(m.method)},
                      {"size", m.size},       {"max_augmentations", m.max_augmentations},
                      {"domain", m.domain},   {"n", m.n}};
  if (m.method == Method::Relief)
    j.update({{"grid", m.grid}, {"texture", m.texture}, {"max_grid", m.max_grid},
              {"occlusion_threshold", m.occlusion_threshold}});
  if (m.method == Method::Mcgim) j.update({{"samples", m.samples}, {"charts", m.charts}});
  if (m.optimize) j["optimize"] = true;
  if (m.proxy_faces != "auto") j["proxy_faces"] = m.proxy_faces;  // absent when auto: earlier journals still match
  if (m.proxy_bricks != 0) j["proxy_bricks"] = m.proxy_bricks;
  if (m.wrap != "off") j["wrap"] = m.wrap;  // absent when off: earlier journals still match
  if (m.adaptive()) j.update({{"sampling", m.sampling}, {"adapt_rounds", m.adapt_rounds}, {"adapt_start", m.adapt_start}});
  if (!m.roi.empty()) j.update({{"roi", m.roi}, {"roi_gain", m.roi_gain}});
  if (!m.codec.empty()) j.update({{"codec", m.codec}, {"rate", m.rate}});  // absent without: journals still match
  return j;
}

OutputSpec output_from_json(const nlohmann::json& j) {
  return {j.at("name").get<std::string>(), MethodOptions::from_json(j)};
}

nlohmann::json job_json(const BatchJob& job) {
  nlohmann::json items = nlohmann::json::array(), outputs = nlohmann::json::array();
  for (const CollectionItem& i : job.items) items.push_back({i.name, i.source, i.label});
  for (const OutputSpec& o : job.outputs) outputs.push_back(output_json(o));
  nlohmann::json j = {{"items", items}, {"outputs", outputs}, {"metric_samples", job.metric_samples}};
  // Where relative sources are read from: a resume from another directory finds the same files.
  std::error_code ec;
  if (const std::filesystem::path here = std::filesystem::current_path(ec); !ec && io::valid_utf8(here.string()))
    j["directory"] = here.string();  // (JSON holds UTF-8 only: elsewhere relative sources read from the current one)
  if (!job.metric) j["metric"] = false;  // absent when on: journals of earlier versions stay resumable
  return j;
}

namespace {

/// Whether `label` is one an earlier gimforge gave the `--list` item `source` (its path as recorded, lexically
/// normal) where today's rule gives another: the line's last directory part, "" for "a.ply", "." for
/// "./a.ply", ".." for "../a.ply" (the folder that holds the file is today's).
bool legacy_label(const std::string& label, const std::string& source) {
  const std::filesystem::path parent = std::filesystem::path(source).parent_path();
  if (label.empty() || label == ".") return parent.empty();
  return label == ".." && parent.filename() == "..";
}

/// `source` of the job `job` describes, relative to the directory it was started in (when it records one:
/// journals of earlier versions do not, and are read from the current one).
std::filesystem::path started_from(const nlohmann::json& job, const std::string& source) {
  const std::filesystem::path path(source);
  const auto directory = job.find("directory");
  return path.is_relative() && directory != job.end() && directory->is_string()
             ? std::filesystem::path(directory->get<std::string>()) / path
             : path;
}

std::string shown(const nlohmann::json& value) {
  return value.is_string() ? fmt::format("'{}'", io::printable(value.get<std::string>())) : value.dump();
}

}  // namespace

std::string job_difference(const nlohmann::json& stored, const nlohmann::json& now, bool* legacy_labels) {
  if (legacy_labels != nullptr) *legacy_labels = false;
  if (stored == now) return {};
  if (!stored.is_object() || !now.is_object()) return "the recorded job is not a job description";
  for (const char* key : {"metric_samples", "metric"}) {
    const nlohmann::json a = stored.value(key, nlohmann::json()), b = now.value(key, nlohmann::json());
    const auto text = [&](const nlohmann::json& v) { return v.is_null() ? std::string(std::string_view(key) == "metric" ? "true" : "unset") : v.dump(); };
    if (a != b) return fmt::format("{} was {}, now {}", key, text(a), text(b));
  }
  const nlohmann::json& so = stored.value("outputs", nlohmann::json::array());
  const nlohmann::json& no = now.at("outputs");
  if (!so.is_array() || so.size() != no.size())
    return fmt::format("the job had {} output(s), now {}", so.is_array() ? so.size() : 0, no.size());
  for (std::size_t i = 0; i < no.size(); ++i) {
    if (so[i] == no[i]) continue;
    std::string name = shown(no[i].value("name", nlohmann::json("?")));
    if (!so[i].is_object()) return fmt::format("output {} was not recorded as options", name);
    // The output the journal holds, which options name differently now ('mcgim_16384_auto' was --samples 16384).
    if (const std::string was = shown(so[i].value("name", nlohmann::json("?"))); was != name)
      name = fmt::format("{} (now {})", was, name);
    for (const auto& [key, value] : no[i].items())
      if (key != "name" && (!so[i].contains(key) || so[i][key] != value))
        return fmt::format("output {}: {} was {}, now {}", name, key,
                           so[i].contains(key) ? shown(so[i][key]) : "unset", shown(value));
    for (const auto& [key, value] : so[i].items())
      if (!no[i].contains(key)) return fmt::format("output {}: {} was {}, now unset", name, key, shown(value));
    return fmt::format("output {} was renamed", name);
  }
  const nlohmann::json& si = stored.value("items", nlohmann::json::array());
  const nlohmann::json& ni = now.at("items");
  if (!si.is_array()) return "the recorded job has no items";
  bool legacy = false;
  std::string first;  // the first item that differs
  for (std::size_t i = 0; i < std::min(si.size(), ni.size()) && first.empty(); ++i) {
    const nlohmann::json& a = si[i];
    const nlohmann::json& b = ni[i];
    if (a == b) continue;
    if (!a.is_array() || a.size() != 3 || !a[0].is_string() || !a[1].is_string() || !a[2].is_string()) {
      first = fmt::format("item {} was not recorded as name, source and label", i);
    } else if (a[1] != b[1] && !io::same_file(started_from(stored, a[1].get<std::string>()),
                                              started_from(now, b[1].get<std::string>()))) {
      first = fmt::format("item {} was {}, now {}", i, shown(a[1]), shown(b[1]));
    } else if (a[0] != b[0]) {
      first = fmt::format("item {} ({}) was named {}, now {}", i, shown(b[1]), shown(a[0]), shown(b[0]));
    } else if (a[2] != b[2]) {
      const std::string& source = a[1].get<std::string>();
      // An earlier gimforge's --list label beside the folder label of today's rule; anything else is a change.
      if (!legacy_label(a[2].get<std::string>(), source) ||
          b[2] != std::filesystem::absolute(started_from(stored, source)).lexically_normal().parent_path().filename().generic_string())
        first = fmt::format("item {} ({}) was labelled {}, now {}", i, shown(b[1]), shown(a[2]), shown(b[2]));
      else
        legacy = true;
    }
  }
  if (si.size() != ni.size())
    return fmt::format("the collection had {} items, now {}{}", si.size(), ni.size(),
                       first.empty() ? "" : " (first difference: " + first + ")");
  if (!first.empty()) return first;
  if (legacy_labels != nullptr) *legacy_labels = legacy;
  return {};
}

}  // namespace gimforge::jobs

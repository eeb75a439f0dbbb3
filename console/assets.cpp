#include "console/assets.h"

#include <fstream>
#include <sstream>

#include "core/error.h"

namespace rangebayes {
namespace {

std::string ContentType(const std::string& name) {
  const auto ends = [&](const char* suffix) {
    const std::string s(suffix);
    return name.size() >= s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0;
  };
  if (ends(".html")) return "text/html; charset=utf-8";
  if (ends(".js")) return "text/javascript; charset=utf-8";
  if (ends(".css")) return "text/css; charset=utf-8";
  if (ends(".png")) return "image/png";
  if (ends(".svg")) return "image/svg+xml";
  return "application/octet-stream";
}

}  // namespace

std::map<std::string, ConsoleAsset> LoadConsoleAssets(const std::string& three_dir) {
  std::map<std::string, ConsoleAsset> assets;
  for (const EmbeddedFile* f = kWebFiles; f->name != nullptr; ++f) {
    const std::string name(f->name);
    ConsoleAsset a{ContentType(name), std::make_shared<const std::string>(f->data, f->size)};
    assets["/" + name] = a;
    if (name == "index.html") assets["/"] = a;
  }
  for (const std::string rel : {"build/three.module.js", "examples/jsm/controls/OrbitControls.js"}) {
    const std::string path = three_dir + "/" + rel;
    std::ifstream in(path, std::ios::binary);
    RB_CHECK(in.good(), path, ": not found (the console's 3D view needs Debian's libjs-three: scripts/setup.sh)");
    std::ostringstream body;
    body << in.rdbuf();
    assets["/three/" + rel] = {ContentType(rel), std::make_shared<const std::string>(body.str())};
  }
  return assets;
}

}  // namespace rangebayes

#include "capture/device_list.h"

#include <fcntl.h>
#include <linux/videodev2.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "capture/v4l2_camera.h"

namespace rangebayes {

std::vector<V4l2DeviceInfo> ListV4l2Devices(V4l2SysCalls& sys, const std::string& dev_dir) {
  std::vector<std::pair<int, std::string>> paths;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dev_dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("video", 0) != 0) continue;
    const std::string number = name.substr(5);
    if (number.empty() || !std::all_of(number.begin(), number.end(), ::isdigit)) continue;
    paths.emplace_back(std::stoi(number), entry.path().string());
  }
  std::sort(paths.begin(), paths.end());
  std::vector<V4l2DeviceInfo> devices;
  for (const auto& [number, path] : paths) {
    V4l2DeviceInfo info;
    info.path = path;
    const int fd = sys.Open(path, O_RDWR | O_NONBLOCK);
    if (fd < 0) {
      info.error = std::strerror(errno);
      devices.push_back(info);
      continue;
    }
    v4l2_capability cap{};
    if (XIoctl(sys, fd, VIDIOC_QUERYCAP, &cap) == 0) {
      info.card = reinterpret_cast<const char*>(cap.card);
      info.driver = reinterpret_cast<const char*>(cap.driver);
      info.bus = reinterpret_cast<const char*>(cap.bus_info);
      const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
      info.can_capture = (caps & V4L2_CAP_VIDEO_CAPTURE) && (caps & V4L2_CAP_STREAMING);
      for (std::uint32_t i = 0; info.can_capture; ++i) {
        v4l2_fmtdesc desc{};
        desc.index = i;
        desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        if (XIoctl(sys, fd, VIDIOC_ENUM_FMT, &desc) < 0) break;
        info.formats.push_back(FourccName(desc.pixelformat));
      }
    } else {
      info.error = std::string("VIDIOC_QUERYCAP failed: ") + std::strerror(errno);
    }
    sys.Close(fd);
    devices.push_back(info);
  }
  return devices;
}

}  // namespace rangebayes

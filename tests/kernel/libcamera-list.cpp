/* libcamera-list.cpp - kernel lane self-test: libcamera's CameraManager finds vimc's camera,
 * which can be acquired and offers a valid viewfinder configuration. The seed of gonio's
 * libcamera shim (C++ behind a C header).
 *
 * Usage: kl-libcamera-list (prints each camera id). */
#include <iostream>
#include <libcamera/libcamera.h>
#include <memory>

#include "tests/test.h"

using namespace libcamera;

static void check_camera(const std::shared_ptr<Camera> &cam)
{
        std::unique_ptr<CameraConfiguration> config;

        CHECK_INT(cam->acquire(), 0);
        config = cam->generateConfiguration({StreamRole::Viewfinder});
        CHECK(config && config->size() == 1);
        CHECK(config->validate() != CameraConfiguration::Invalid);
        std::cout << cam->id() << ": " << config->at(0).toString() << std::endl;
        CHECK_INT(cam->release(), 0);
}

int main()
{
        auto cm = std::make_unique<CameraManager>();
        bool vimc = false;

        CHECK_INT(cm->start(), 0);
        for (const auto &cam : cm->cameras()) {
                check_camera(cam);
                vimc = vimc || cam->id().find("vimc") != std::string::npos;
        }
        CHECK(vimc);
        cm->stop();
        return 0;
}

// The rigid gap diagnosis's synthetic bench cases: tosses rendered with one
// catalogue effect (or none), sensor noise and a label kept apart from the
// capture (docs/rigid.md, "Gap diagnosis"). The model is in rigid_model.cpp. Design notes in docs/rigid.md ("Gap diagnosis").

#include "flowvid/gap/rigid_model.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/json_fields.hpp"
#include "flowvid/metrics/silhouette.hpp"
#include "flowvid/render/rasterizer.hpp"
#include "flowvid/rigid/rectify.hpp"
#include "flowvid/threads.hpp"

#include "rigid_model_parts.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace flowvid::gap {

using rigid::FlightEffects;
using rigid::FlightParameters;
using rigid::RigidBody;
using rigid::RigidState;
using namespace rigid_parts;

// ---- Bench cases -------------------------------------------------------------------------

namespace {

// Sensor noise as in the captures: Gaussian per pixel, spatially correlated
// over 3 x 3 pixels (a box mean of white noise with three times the sigma).
std::vector<float> correlated_noise(int width, int height, double sigma, Random& random) {
    std::vector<double> white(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
    for (double& v : white) v = 3.0 * sigma * random.normal();
    std::vector<float> out(white.size());
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            double sum = 0.0;
            int n = 0;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int xx = x + dx, yy = y + dy;
                    if (xx < 0 || yy < 0 || xx >= width || yy >= height) continue;
                    sum += white[static_cast<std::size_t>(yy) * static_cast<std::size_t>(width) + static_cast<std::size_t>(xx)];
                    ++n;
                }
            // Border pixels average fewer samples: rescale to the same sigma.
            out[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)] =
                static_cast<float>(sum / n * std::sqrt(static_cast<double>(n)) / 3.0);
        }
    return out;
}

std::string read_binary(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path, "", "cannot open the file", "check that it exists and is readable");
    std::ostringstream bytes;
    bytes << in.rdbuf();
    if (in.bad()) throw IoError(path, "", "cannot read the file");
    return bytes.str();
}

}  // namespace

RigidCase write_rigid_case(const std::string& folder, const formats::Capture& template_capture, const EffectValues& effects,
                           std::uint64_t seed, const RigidCaseSettings& settings) {
    const formats::Capture& tmpl = template_capture;
    Diagnostics diagnostics(tmpl.json_path.empty() ? tmpl.folder : tmpl.json_path);
    if (!tmpl.is_rigid())
        diagnostics.error("/kind", "a rigid bench case needs a rigid.toss template, this one is '" + tmpl.kind + "'",
                          "pass one of the rigid captures");
    if (!tmpl.rigid)
        diagnostics.error("/rigid", "no rigid block: the template has no body to toss", "use a rigid.toss capture as template");
    else if (tmpl.rigid->body_mesh.vertices_m.empty())
        diagnostics.error("/rigid/mesh", "the template's mesh was not loaded", "read the template with formats::read_capture");
    if (!tmpl.camera) diagnostics.error("/camera", "no camera to film the toss with", "add the camera block");
    const double fps = settings.fps > 0.0 ? settings.fps : tmpl.fps;
    if (!(fps > 0.0)) diagnostics.error("/fps", "no frame rate", "set fps in the template or RigidCaseSettings::fps");
    const int frame_count = settings.frame_count > 0 ? settings.frame_count : tmpl.frames.count;
    if (frame_count < 3) diagnostics.error("/frames/count", "a toss needs at least 3 frames", "set RigidCaseSettings::frame_count");
    diagnostics.throw_if_errors();
    const FlightEffects terms = flight_effects(effects);

    const RigidBody body = RigidBody::from_capture(*tmpl.rigid);
    formats::CameraModel camera = *tmpl.camera;
    camera.camera_from_world = Eigen::Matrix4d::Identity();  // rigid tosses: world = camera frame
    const int width = camera.width, height = camera.height;
    const double f = 0.5 * (camera.K(0, 0) + camera.K(1, 1));
    const Eigen::Matrix3d K_inv = camera.K.inverse();
    double radius = 0.0;
    for (const Eigen::Vector3d& v : body.mesh.vertices_m) radius = std::max(radius, (v - body.center_of_mass_m).norm());
    radius = std::max(radius, 1e-3);

    std::vector<double> times;
    for (int i = 0; i < frame_count; ++i) times.push_back(i / fps);
    const double duration = times.back();
    rigid::SimulationSettings simulation;
    simulation.max_step_s = settings.max_step_s > 0.0 ? settings.max_step_s : 1.0 / 960.0;
    simulation.effects = terms;

    // Draw tosses until one stays in view: start and end points low in the
    // image, the launch velocity shot so that the COM lands on the end point
    // with the effects included (drag shortens a flight).
    Random random(seed);
    FlightParameters initial;
    rigid::Trajectory motion;
    int attempts = 0;
    bool found = false;
    while (!found && attempts < std::max(1, settings.max_attempts)) {
        ++attempts;
        const double size_px = random.uniform(settings.size_min_px, settings.size_max_px);
        const double z0 = f * 2.0 * radius / size_px;
        FlightParameters p;
        p.gravity = rigid::GravityAngles{random.uniform(-settings.gravity_tilt_max_rad, settings.gravity_tilt_max_rad),
                                         random.uniform(-settings.gravity_roll_max_rad, settings.gravity_roll_max_rad)};
        const Eigen::Vector3d u0(random.uniform(0.15, 0.85) * width, random.uniform(0.6, 0.85) * height, 1.0);
        const Eigen::Vector3d u1(random.uniform(0.15, 0.85) * width, random.uniform(0.6, 0.85) * height, 1.0);
        const double z1 = z0 * random.uniform(0.85, 1.15);
        const Eigen::Vector3d X0 = z0 * (K_inv * u0), X1 = z1 * (K_inv * u1);
        Eigen::Vector4d q(random.normal(), random.normal(), random.normal(), random.normal());
        q.normalize();
        Eigen::Vector3d axis(random.normal(), random.normal(), random.normal());
        axis.normalize();
        p.com_m = X0;
        p.orientation = Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
        p.angular_velocity_rad_per_s = axis * random.uniform(settings.spin_min_rad_per_s, settings.spin_max_rad_per_s);
        p.com_velocity_m_per_s = (X1 - X0 - 0.5 * p.gravity_m_per_s2() * duration * duration) / duration;
        for (int shot = 0; shot < 8; ++shot) {
            const RigidState end = rigid::simulate(body, p, {duration}, simulation).states.front();
            if (!finite_state(end)) break;
            p.com_velocity_m_per_s += (X1 - end.com_m) / duration;
        }
        motion = rigid::simulate(body, p, times, simulation);
        found = true;
        std::vector<Eigen::Vector2d> pixels;
        for (const RigidState& s : motion.states) {
            if (!finite_state(s)) {
                found = false;
                break;
            }
            const std::vector<Eigen::Vector3d> points = camera_points(body, s);
            render::project_camera_points(camera, points, pixels);
            for (std::size_t k = 0; k < points.size() && found; ++k)
                found = points[k].z() > 0.05 && pixels[k].allFinite() && pixels[k].x() >= settings.margin_px &&
                        pixels[k].y() >= settings.margin_px && pixels[k].x() <= width - 1 - settings.margin_px &&
                        pixels[k].y() <= height - 1 - settings.margin_px;
            if (!found) break;
        }
        if (found) initial = p;
    }
    if (!found)
        throw std::runtime_error("write_rigid_case: no toss of " + std::to_string(attempts) +
                                 " draws stayed in view (effects too strong or the image too small for the body)");

    // Backdrop colour: the template's background, on average.
    Eigen::Vector3d backdrop(0.42, 0.43, 0.45);
    if (!tmpl.background.empty()) {
        const formats::Image image = formats::load_image(tmpl.resolve(tmpl.background), 3);
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (std::size_t i = 0; i + 2 < image.pixels.size(); i += 3) sum += Eigen::Vector3d(image.pixels[i], image.pixels[i + 1], image.pixels[i + 2]);
        const double n = static_cast<double>(image.pixels.size() / 3);
        if (n > 0.0) backdrop = sum / n;
    }
    const Eigen::Vector3d albedo(0.80, 0.52, 0.27);                     // a light wood, as in the captures
    const Eigen::Vector3d light = Eigen::Vector3d(-0.4, -0.7, -0.6).normalized();  // towards the light: up-left, camera side

    namespace fs = std::filesystem;
    std::error_code error;
    fs::create_directories(fs::path(folder) / "frames", error);
    if (!error) fs::create_directories(fs::path(folder) / "masks", error);
    if (error) throw IoError(folder, "", "cannot create the case folder: " + error.message(), "check the path and permissions");

    auto write_rgb = [&](const std::string& path, const std::vector<Eigen::Vector3f>& rgb, const std::vector<float>& noise) {
        formats::Image image;
        image.width = width;
        image.height = height;
        image.channels = 3;
        image.pixels.resize(rgb.size() * 3);
        for (std::size_t i = 0; i < rgb.size(); ++i)
            for (int c = 0; c < 3; ++c) image.pixels[3 * i + static_cast<std::size_t>(c)] = std::clamp(rgb[i][c] + noise[i], 0.0f, 1.0f);
        rigid::write_png(path, image);
    };
    const std::size_t pixel_count = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    {
        Random noise_random(derive_seed(seed, 0));
        const std::vector<float> noise = correlated_noise(width, height, settings.noise_sigma, noise_random);
        write_rgb((fs::path(folder) / "background.png").string(), std::vector<Eigen::Vector3f>(pixel_count, backdrop.cast<float>()), noise);
    }
    const int threads = resolve_thread_count(settings.threads);
    rigid::parallel_for(times.size(), threads, [&](std::size_t i, int) {
        const RigidState& state = motion.states[i];
        const std::vector<Eigen::Vector3d> points = camera_points(body, state);
        render::RasterSettings raster;
        raster.supersampling = std::clamp(settings.supersampling, 1, 8);
        raster.region = projected_region(camera, points);
        const render::Framebuffer fb = render::rasterize(points, body.mesh.triangles, render::VertexSpace::camera, camera, raster);

        std::vector<Eigen::Vector3f> rgb(pixel_count, backdrop.cast<float>());
        metrics::Silhouette mask(width, height);
        const render::PixelRect& r = fb.region;
        for (int y = r.y0; y < r.y1; ++y)
            for (int x = r.x0; x < r.x1; ++x) {
                const std::size_t at = fb.index_of(x, y);
                const double coverage = fb.coverage[at];
                if (coverage <= 0.0) continue;
                double shade = 0.65;  // edge pixels whose centre misses the body
                const std::int32_t t = fb.triangle[at];
                if (t >= 0) {
                    const std::array<int, 3>& tri = body.mesh.triangles[static_cast<std::size_t>(t)];
                    const Eigen::Vector3d& P0 = points[static_cast<std::size_t>(tri[0])];
                    Eigen::Vector3d n = (points[static_cast<std::size_t>(tri[1])] - P0).cross(points[static_cast<std::size_t>(tri[2])] - P0);
                    if (n.norm() > 0.0) n.normalize();
                    if (n.dot(P0) > 0.0) n = -n;  // the side facing the camera
                    shade = 0.3 + 0.7 * std::max(0.0, n.dot(light));
                }
                const Eigen::Vector3d colour = coverage * shade * albedo + (1.0 - coverage) * backdrop;
                rgb[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)] = colour.cast<float>();
                mask.set(x, y, coverage >= 0.5);
            }
        Random noise_random(derive_seed(seed, i + 1));
        const std::vector<float> noise = correlated_noise(width, height, settings.noise_sigma, noise_random);
        char name[32];
        std::snprintf(name, sizeof name, "%06d.png", static_cast<int>(i) + 1);
        write_rgb((fs::path(folder) / "frames" / name).string(), rgb, noise);
        rigid::write_png((fs::path(folder) / "masks" / name).string(), metrics::silhouette_to_image(mask));
    });

    const std::string mesh_bytes = read_binary(tmpl.resolve(tmpl.rigid->mesh));
    formats::write_file_atomically((fs::path(folder) / "body.glb").string(),
                                   [&](std::ostream& out) { out.write(mesh_bytes.data(), static_cast<std::streamsize>(mesh_bytes.size())); });

    formats::Capture capture;
    capture.folder = folder;
    capture.json_path = (fs::path(folder) / "capture.json").string();
    capture.kind = "rigid.toss";
    capture.fps = fps;
    capture.frames.pattern = "frames/%06d.png";
    capture.frames.first = 1;
    capture.frames.count = frame_count;
    capture.background = "background.png";
    capture.masks = "masks/%06d.png";
    capture.camera = camera;
    capture.world = formats::WorldSpec{std::nullopt, "unknown: world frame = camera frame; estimate gravity in camera space"};
    capture.rigid = *tmpl.rigid;
    capture.rigid->mesh = "body.glb";
    capture.rigid->body_mesh = {};
    capture.source = {{"origin", "synthetic: flowvid gap::write_rigid_case"}, {"template", tmpl.folder}, {"seed", seed}};
    const std::string text = formats::dump_json(formats::capture_to_json(capture));
    formats::write_file_atomically(capture.json_path, [&](std::ostream& out) { out << text; });

    RigidCase result;
    result.folder = folder;
    result.initial = initial;
    result.effects = terms;
    result.effect_values = effects;
    result.seed = seed;
    result.frame_count = frame_count;
    result.fps = fps;
    result.attempts = attempts;
    return result;
}

}  // namespace flowvid::gap

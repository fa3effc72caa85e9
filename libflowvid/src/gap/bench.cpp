#include "flowvid/gap/bench.hpp"
#include "flowvid/random.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/gap/cloth_model.hpp"
#include "flowvid/cloth_fit/cloth_fit.hpp"
#include "flowvid/video/stripe_render.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <stdexcept>

namespace flowvid::gap {

namespace {

std::vector<std::string> default_effects(bool rigid) {
    std::vector<std::string> names;
    for (const Effect& e : effect_catalogue()) {
        if (e.domain == EffectDomain::model) continue;  // the diagnoser's own model: nothing footage hides
        if (e.domain != EffectDomain::rigid || rigid) names.push_back(e.name);
    }
    return names;
}

// Log-uniform in [lo, hi], with a random sign when `signed_value`.
double draw(Random& random, double lo, double hi, bool signed_value = false) {
    const double magnitude = lo * std::pow(hi / lo, random.uniform());
    return signed_value && random.uniform() < 0.5 ? -magnitude : magnitude;
}

// Magnitudes are log-uniform over what a swatch test can meet, times
// `strength`; rates and angles of direction are not scaled.
EffectValues draw_values(const std::string& name, double strength, Random& random) {
    const Effect& effect = find_effect(name);
    Eigen::VectorXd v = neutral_values(effect);
    const auto magnitude = [&](double lo, double hi, bool signed_value = false) {
        return strength * draw(random, lo, hi, signed_value);
    };
    if (name == "drag_nonlinear") {
        v << 0.0, 0.0;  // the fabric's own nonlinear drag (bench_base_material drops it from the base)
    } else if (name == "wind") {
        // Pushing as on a plate: 0.25 m/s leans cotton by about 2 degrees,
        // 1.2 m/s by about 35 (silk, about half as heavy, further).
        const double speed = magnitude(0.25, 1.2), heading = 2.0 * std::numbers::pi * random.uniform();
        v(0) = speed * std::cos(heading);
        v(1) = speed * std::sin(heading);
        v(2) = 0.0;
        if (random.uniform() < 0.5) {
            v(3) = speed * (0.3 + 0.7 * random.uniform());
            v(4) = draw(random, 0.5, 2.0);
        }
    } else if (name == "anisotropy") {
        v(0) = magnitude(0.3, 1.5, true);
        v(1) = magnitude(0.1, 0.7, true);
    } else if (name == "hysteresis") {
        v(0) = magnitude(0.5, 15.0);
    } else if (name == "pin_lag") {
        v(0) = magnitude(0.02, 0.13, true);
    } else if (name == "pin_slip") {
        v(0) = magnitude(0.005, 0.06);
    } else if (name == "camera_roll") {
        v(0) = magnitude(0.005, 0.08, true);
    } else if (name == "lens_distortion") {
        v(0) = magnitude(0.02, 0.4, true);
        v(1) = random.uniform() < 0.5 ? 0.0 : magnitude(0.02, 0.2, true);
    } else if (name == "rolling_shutter") {
        v(0) = magnitude(0.004, 0.033, true);
    } else if (name == "motion_blur") {
        v(0) = magnitude(0.004, 0.033);
    } else if (name == "air_drag") {
        v(0) = magnitude(0.02, 0.5);
        v(1) = random.uniform() < 0.5 ? 0.0 : magnitude(0.2, 3.0);
    } else if (name == "inertia_error") {
        v(0) = magnitude(0.05, 0.4, true);
        v(1) = magnitude(0.05, 0.4, true);
    } else {
        throw std::invalid_argument("flowvid bench gap cannot make cases of '" + name + "'");
    }
    // Keep within the catalogue's ranges (what the diagnoser can fit).
    for (std::size_t i = 0; i < effect.parameters.size(); ++i)
        v(static_cast<Eigen::Index>(i)) = std::clamp(v(static_cast<Eigen::Index>(i)), effect.parameters[i].lower, effect.parameters[i].upper);
    return {{name, v}};
}

std::uint8_t srgb_byte(double linear, double noise) {
    linear = std::clamp(linear, 0.0, 1.0);
    const double encoded = linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
    return static_cast<std::uint8_t>(std::clamp(std::lround(255.0 * (encoded + noise)), 0L, 255L));
}

// Gaussian noise of RMS sigma, correlated over 3x3 pixels (as after demosaicing).
cv::Mat correlated_noise(int width, int height, double sigma, Random& random) {
    cv::Mat white(height, width, CV_32F);
    const double white_sigma = 3.0 * sigma;  // a 3x3 box divides the RMS by 3
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) white.at<float>(y, x) = static_cast<float>(random.normal(0.0, white_sigma));
    cv::Mat out;
    cv::blur(white, out, cv::Size(3, 3), cv::Point(-1, -1), cv::BORDER_REFLECT);
    return out;
}

void write_png(const std::string& path, const cv::Mat& image) {
    std::vector<std::uint8_t> bytes;
    if (!cv::imencode(".png", image, bytes)) throw std::runtime_error("cannot encode " + path);
    formats::write_file_atomically(path, [&](std::ostream& out) {
        out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    });
}

cv::Mat rgb_frame(const video::ImageF& linear, const cv::Mat& noise) {
    cv::Mat out(linear.height, linear.width, CV_8UC3);
    for (int y = 0; y < linear.height; ++y)
        for (int x = 0; x < linear.width; ++x) {
            const std::uint8_t b = srgb_byte(linear.pixels[linear.index(x, y)], noise.at<float>(y, x));
            out.at<cv::Vec3b>(y, x) = cv::Vec3b(b, b, b);
        }
    return out;
}

cloth_fit::ClothTrial scene_trial(const formats::Capture& scene, int frames) {
    cloth_fit::ClothTrial trial;
    trial.name = scene.folder;
    trial.experiment = cloth::experiment_from_capture(scene);
    trial.camera = *scene.camera;
    trial.projector = *scene.projector;
    const int simulated = std::min(frames + 2, trial.experiment.frame_count);
    trial.experiment.frame_count = simulated;
    for (cloth::PinTrajectory& pin : trial.experiment.pins)
        if (static_cast<int>(pin.positions_m.size()) > simulated) pin.positions_m.resize(static_cast<std::size_t>(simulated));
    return trial;
}

cloth::SwatchOptions fine_options(const BenchSettings& settings, const formats::Capture& scene, int threads) {
    cloth::SwatchOptions options;
    options.rows = settings.rows;
    options.cols = settings.cols;
    options.simulation.integrator = settings.integrator;
    options.simulation.implicit_substeps_per_frame = settings.implicit_substeps;
    options.simulation.threads = std::max(1, threads);
    if (scene.world && scene.world->gravity_m_per_s2) options.environment.gravity_m_per_s2 = *scene.world->gravity_m_per_s2;
    return options;
}

}  // namespace

std::vector<BenchCase> draw_bench_cases(int count, std::uint64_t seed, int scenes, int fabrics, const BenchSettings& settings,
                                        int rigid_scenes) {
    if (count < 1) throw std::invalid_argument("flowvid bench gap: --cases must be at least 1");
    if (scenes < 1 || fabrics < 1) throw std::invalid_argument("flowvid bench gap: needs at least one scene and one fabric");
    const std::vector<std::string> effects = settings.effects.empty() ? default_effects(rigid_scenes > 0) : settings.effects;
    int rigid_effects = 0;
    for (const std::string& e : effects) {
        const EffectDomain domain = find_effect(e).domain;
        const bool rigid = domain == EffectDomain::rigid;
        if (domain == EffectDomain::model)
            throw std::invalid_argument("flowvid bench gap: '" + e + "' is a term of the cloth model, not an effect footage can hide; "
                                        "diagnose a preset fitted without it instead");
        if (rigid && rigid_scenes < 1) throw std::invalid_argument("flowvid bench gap: '" + e + "' needs a rigid scene (--rigid-scene)");
        rigid_effects += rigid ? 1 : 0;
    }
    Random random(seed);
    std::vector<BenchCase> cases;
    // The effect-free cases are placed evenly (about none_share of them), the
    // effects cycle through a shuffled order so every effect is represented.
    std::vector<std::string> order = effects;
    random.shuffle(order.begin(), order.end());
    std::size_t next = 0;
    double none_debt = 0.0;
    for (int i = 0; i < count; ++i) {
        BenchCase c;
        char id[32];
        std::snprintf(id, sizeof id, "case-%03d", i + 1);
        c.id = id;
        c.scene = static_cast<int>(random.uniform() * scenes) % scenes;
        c.fabric = static_cast<int>(random.uniform() * fabrics) % fabrics;
        none_debt += settings.none_share;
        if (none_debt >= 1.0 - 1e-9 || effects.empty()) {
            none_debt -= 1.0;
            c.effect = "none";
            c.rigid = rigid_effects > 0 && random.uniform() * static_cast<double>(effects.size()) < rigid_effects;
        } else {
            c.effect = order[next++ % order.size()];
            c.values = draw_values(c.effect, settings.strength, random);
            c.rigid = find_effect(c.effect).domain == EffectDomain::rigid;
        }
        if (c.rigid) c.scene = static_cast<int>(random.uniform() * rigid_scenes) % rigid_scenes;
        cases.push_back(std::move(c));
    }
    return cases;
}

EffectValues weakened(const EffectValues& values) {
    EffectValues out = values;
    for (auto& [name, v] : out) {
        const Eigen::VectorXd neutral = neutral_values(find_effect(name));
        v = neutral + 0.5 * (v - neutral);
    }
    return out;
}

cloth::ClothMaterial bench_base_material(const BenchCase& c, const cloth::ClothMaterial& fabric) {
    cloth::ClothMaterial base = fabric;
    if (c.effect == "drag_nonlinear") {
        base.drag_normal_kg_per_m3 = 0.0;
        base.drag_degradation_s2_per_m2 = 0.0;
    }
    return base;
}

void write_cloth_case(const std::string& folder, const BenchCase& c, const formats::Capture& scene,
                      const cloth::ClothMaterial& fabric, const BenchSettings& settings, int threads) {
    if (!scene.is_cloth() || !scene.camera || !scene.projector || !scene.swatch)
        throw std::invalid_argument(scene.json_path + ": a bench scene must be a cloth capture");
    namespace fs = std::filesystem;
    fs::create_directories(fs::path(folder) / "frames");
    fs::create_directories(fs::path(folder) / "masks");
    const cloth_fit::ClothTrial trial = scene_trial(scene, settings.frames);
    // drag_nonlinear's values are the fabric's own: the base lacks them.
    EffectValues effects = c.values;
    if (c.effect == "drag_nonlinear")
        effects["drag_nonlinear"] = (Eigen::VectorXd(2) << fabric.drag_normal_kg_per_m3, fabric.drag_degradation_s2_per_m2).finished();
    const cloth::ClothMaterial base = bench_base_material(c, fabric);
    ClothScenario scenario = apply_cloth_effects(trial, base, fine_options(settings, scene, threads), effects);
    // Hung cloth has several equilibria: the first bow that converges.
    cloth::SwatchRun run;
    for (const double bow : {1.0, -1.0, 0.0}) {
        scenario.options.initial_bow = bow;
        run = cloth::simulate_swatch(scenario.experiment, scenario.material, scenario.options);
        if (cloth_fit::usable_frames(run) >= settings.frames) break;
    }
    if (cloth_fit::usable_frames(run) < settings.frames)
        throw std::runtime_error(c.id + ": the footage simulation failed: " + run.simulation.report.reason);

    video::StripeRenderSettings look;
    look.shading = video::StripeShading::lambertian;
    look.background = 0.08f;
    video::StripeRenderer renderer(scenario.camera, trial.projector, look);
    Random random(seed_from_text(c.id.data(), c.id.size()) ^ 0x6a09e667f3bcc909ULL);
    const int width = scenario.camera.width, height = scenario.camera.height;
    for (int k = 0; k < settings.frames; ++k) {
        const video::StripeImage filmed = film_frame(scenario, run, k, renderer);
        char name[32];
        std::snprintf(name, sizeof name, "%06d.png", k + 1);
        write_png((fs::path(folder) / "frames" / name).string(),
                  rgb_frame(filmed.image, correlated_noise(width, height, settings.noise_sigma, random)));
        cv::Mat mask(height, width, CV_8UC1);
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) mask.at<std::uint8_t>(y, x) = filmed.silhouette.at(x, y) ? 255 : 0;
        write_png((fs::path(folder) / "masks" / name).string(), mask);
    }
    write_png((fs::path(folder) / "background.png").string(),
              rgb_frame(video::ImageF(width, height, look.background), correlated_noise(width, height, settings.noise_sigma, random)));

    formats::Capture out = scene;
    out.folder = folder;
    out.frames = {"frames/%06d.png", "", 1, settings.frames};
    out.masks = "masks/%06d.png";
    out.background = "background.png";
    for (formats::Pin& pin : out.swatch->pins)
        if (static_cast<int>(pin.positions_m.size()) > settings.frames) pin.positions_m.resize(static_cast<std::size_t>(settings.frames));
    out.frames.count = settings.frames;
    out.source = {{"generator", "flowvid bench gap"},
                  {"scene", fs::path(scene.folder).filename().string()},
                  {"licence", "CC0-1.0 (generated)"}};
    const nlohmann::json document = formats::capture_to_json(out);
    formats::write_file_atomically((fs::path(folder) / "capture.json").string(),
                                   [&](std::ostream& o) { o << document.dump(1) << '\n'; });
}

double measure_effect_to_noise(const std::string& folder, const BenchCase& c, const cloth::ClothMaterial& fabric,
                               const BenchSettings& settings, int threads) {
    const formats::Capture capture = formats::read_capture(folder);
    cloth_fit::TrialLoadSettings load;
    load.waving_frames = settings.frames;
    load.full_weight_frames = settings.frames;
    std::vector<cloth_fit::ClothTrial> trials{cloth_fit::load_trial(capture, load)};
    ClothGapSettings gap;
    gap.fit.swatch = fine_options(settings, capture, threads);
    gap.threads = threads;
    const ClothGapModel model(std::move(trials), bench_base_material(c, fabric), gap);
    const Residuals r = model.evaluate({});
    double sum = 0.0;
    for (const FrameResidual& f : r.frames) sum += f.error / f.floor;
    return r.frames.empty() ? 0.0 : sum / static_cast<double>(r.frames.size());
}

}  // namespace flowvid::gap

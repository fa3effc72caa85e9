// Contacts inside the integrator: a swatch dropped on a sphere, a plane or a
// capsule never sinks beyond the contact layer (distance to the surface stays
// positive), with and without self-collision and friction.

#include "flowvid/cloth/simulator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace fc = flowvid::cloth;

namespace {

fc::ClothMaterial cotton_like() {
    fc::ClothMaterial m;
    m.areal_density_kg_per_m2 = 0.15;
    m.stretch_warp_N_per_m = m.stretch_weft_N_per_m = 150.0;
    m.shear_N_per_m = 90.0;
    m.bend_N_m = 1e-6;
    m.stretch_warp_damping_N_s_per_m = m.stretch_weft_damping_N_s_per_m = 0.01;
    m.shear_damping_N_s_per_m = 0.005;
    m.drag_normal_kg_per_m3 = 0.5;
    m.drag_tangential_kg_per_m2_s = 0.1;
    return m;
}

struct Drop {
    double min_distance_m = 1e300;  // over all frames and vertices
    fc::SimulationReport report;
};

// Drops a horizontal 0.3 m swatch from `height` above the top of the body.
Drop drop_on(const fc::Collider& body, const std::function<double(const Eigen::Vector3d&)>& surface_distance,
             double top_z, fc::Integrator integrator, bool self_contact, double friction) {
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.3, 0.3, 12, 12);
    fc::Environment env;
    env.colliders = {body};
    env.contact.thickness_m = 0.004;
    env.contact.friction_coefficient = friction;
    env.self_contact.enabled = self_contact;
    fc::ClothModel model(mesh, cotton_like(), env);
    Eigen::VectorXd x(3 * mesh.vertex_count());
    for (int i = 0; i < mesh.vertex_count(); ++i) {
        const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
        x.segment<3>(3 * i) = Eigen::Vector3d(uv.x() - 0.15 + 0.013, uv.y() - 0.15 - 0.007, top_z + 0.05);
    }
    fc::SimulationSettings s;
    s.integrator = integrator;
    Drop drop;
    const fc::SimulationResult r = fc::simulate(model, {}, x, Eigen::VectorXd::Zero(x.size()), 0.0, 30.0, 22, s,
                                                [](const flowvid::ProgressReport&) { return true; });
    drop.report = r.report;
    for (const Eigen::VectorXd& f : r.frames)
        for (int i = 0; i < mesh.vertex_count(); ++i)
            drop.min_distance_m = std::min(drop.min_distance_m, surface_distance(f.segment<3>(3 * i)));
    return drop;
}

}  // namespace

TEST(ClothCollision, DroppedSwatchDoesNotPenetrateBodies) {
    const Eigen::Vector3d centre(0.0, 0.0, 0.5);
    const double radius = 0.08;
    struct Body {
        const char* name;
        fc::Collider collider;
        std::function<double(const Eigen::Vector3d&)> distance;
        double top_z;
    };
    const Eigen::Vector3d a(-0.1, 0.02, 0.5), b(0.1, -0.02, 0.5);
    const Body bodies[] = {
        {"sphere", fc::SphereCollider{centre, radius}, [&](const Eigen::Vector3d& p) { return (p - centre).norm() - radius; },
         centre.z() + radius},
        {"plane", fc::PlaneCollider{Eigen::Vector3d(0, 0, 0.5), Eigen::Vector3d(0.1, 0.0, 1.0)},
         [](const Eigen::Vector3d& p) { return (p - Eigen::Vector3d(0, 0, 0.5)).dot(Eigen::Vector3d(0.1, 0, 1).normalized()); },
         0.52},
        {"capsule", fc::CapsuleCollider{a, b, 0.05},
         [&](const Eigen::Vector3d& p) {
             const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
             return (p - (a + t * (b - a))).norm() - 0.05;
         },
         0.55},
    };
    for (const Body& body : bodies) {
        for (fc::Integrator integrator : {fc::Integrator::rk4_adaptive, fc::Integrator::implicit_euler}) {
            for (bool self : {false, true}) {
                const Drop d = drop_on(body.collider, body.distance, body.top_z, integrator, self, self ? 0.3 : 0.0);
                std::printf("[ measured ] %s, %s, self-contact %d: %s, closest approach %.2f mm (layer 4 mm)\n", body.name,
                            fc::integrator_name(integrator), self, fc::status_name(d.report.status), 1e3 * d.min_distance_m);
                EXPECT_TRUE(d.report.ok()) << body.name << ": " << d.report.reason;
                EXPECT_GT(d.min_distance_m, 0.0) << body.name << " " << fc::integrator_name(integrator);
                EXPECT_LT(d.min_distance_m, 0.004) << "the swatch never reached " << body.name;
            }
        }
    }
}

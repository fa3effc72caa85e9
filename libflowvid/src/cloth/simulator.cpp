#include "flowvid/cloth/simulator.hpp"

#include "flowvid/cloth/linear_solve.hpp"
#include "flowvid/thread_pool.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

namespace flowvid::cloth {

namespace {

// Butcher tableaux with an embedded lower-order solution; e = b - b_hat.
struct Tableau {
    int stages;
    int error_order;  // order of the lower solution + 1, for the step controller
    bool fsal;
    double c[7];
    double a[7][7];
    double b[7];
    double e[7];
};

const Tableau kDormandPrince = {
    7,
    5,
    true,
    {0.0, 1.0 / 5, 3.0 / 10, 4.0 / 5, 8.0 / 9, 1.0, 1.0},
    {{0},
     {1.0 / 5},
     {3.0 / 40, 9.0 / 40},
     {44.0 / 45, -56.0 / 15, 32.0 / 9},
     {19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729},
     {9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656},
     {35.0 / 384, 0.0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84}},
    {35.0 / 384, 0.0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84, 0.0},
    {71.0 / 57600, 0.0, -71.0 / 16695, 71.0 / 1920, -17253.0 / 339200, 22.0 / 525, -1.0 / 40},
};

// Classic RK4, propagated, with an embedded third-order solution that
// replaces k4 by k5 = f(t + h, y_new) (first same as last: still 4 force
// evaluations per step). Chosen as the default because the stability function
// of classic RK4 stays inside the unit circle on the imaginary axis up to
// |h w| = 2.83: undamped oscillations lose a little energy instead of gaining
// it, which Dormand-Prince 5(4) does at |h w| ~ 1..3.3 (see docs/cloth_model.md).
const Tableau kRungeKutta43 = {
    5,
    4,
    true,
    {0.0, 0.5, 0.5, 1.0, 1.0},
    {{0}, {0.5}, {0.0, 0.5}, {0.0, 0.0, 1.0}, {1.0 / 6, 1.0 / 3, 1.0 / 3, 1.0 / 6}},
    {1.0 / 6, 1.0 / 3, 1.0 / 3, 1.0 / 6, 0.0},
    {0.0, 0.0, 0.0, 1.0 / 6, -1.0 / 6},
};

const Tableau kBogackiShampine = {
    4,
    3,
    true,
    {0.0, 0.5, 0.75, 1.0},
    {{0}, {0.5}, {0.0, 0.75}, {2.0 / 9, 1.0 / 3, 4.0 / 9}},
    {2.0 / 9, 1.0 / 3, 4.0 / 9, 0.0},
    {2.0 / 9 - 7.0 / 24, 1.0 / 3 - 1.0 / 4, 4.0 / 9 - 1.0 / 3, -1.0 / 8},
};

bool all_finite(const Eigen::VectorXd& v) { return std::isfinite(v.sum()) && v.allFinite(); }

}  // namespace

const char* integrator_name(Integrator integrator) {
    switch (integrator) {
        case Integrator::rk4_adaptive: return "rk4_adaptive";
        case Integrator::dopri54: return "rk45_adaptive";
        case Integrator::bogacki_shampine32: return "rk23_adaptive";
        case Integrator::implicit_euler: return "implicit_euler";
        case Integrator::bdf2: return "bdf2";
    }
    return "?";
}

const std::map<std::string, Integrator>& integrators_by_short_name() {
    static const std::map<std::string, Integrator> table = {
        {"rk4", Integrator::rk4_adaptive},     {"dopri54", Integrator::dopri54}, {"bs32", Integrator::bogacki_shampine32},
        {"implicit", Integrator::implicit_euler}, {"bdf2", Integrator::bdf2}};
    return table;
}

const char* integrator_short_name(Integrator integrator) {
    for (const auto& [name, value] : integrators_by_short_name())
        if (value == integrator) return name.c_str();
    return "?";
}

std::optional<Integrator> integrator_from_name(const std::string& name) {
    for (const auto& [short_name, integrator] : integrators_by_short_name())
        if (name == short_name || name == integrator_name(integrator)) return integrator;
    return std::nullopt;
}

const char* status_name(SimulationReport::Status status) {
    switch (status) {
        case SimulationReport::Status::ok: return "ok";
        case SimulationReport::Status::blew_up: return "blew_up";
        case SimulationReport::Status::step_underflow: return "step_underflow";
        case SimulationReport::Status::cancelled: return "cancelled";
    }
    return "?";
}

struct ClothSimulator::Workspace {
    // Explicit stages: velocity and acceleration of each stage state.
    Eigen::VectorXd kx[7], kv[7];
    Eigen::VectorXd xs, vs, x_new, v_new, force;
    Eigen::VectorXd bending_force_change;  // bending memory: the FSAL stage's correction
    bool have_first = false;  // kx[0], kv[0] valid for the current state (FSAL)
    // Implicit.
    Linearization lin;
    BlockSparseMatrix J;
    BlockSparseMatrix system_matrix;  // M - J, for the Gauss-Seidel sweeps
    Eigen::VectorXd extra_product;
    std::vector<Eigen::Matrix3d> diagonal;
    Eigen::VectorXd rhs, delta, delta_previous, tmp, x_hat, v_hat, v1, pinned_only;
    ConjugateGradient cg;
};

ClothSimulator::ClothSimulator(ClothModel& model, std::vector<PinnedVertex> pins, SimulationSettings settings)
    : m_model(model), m_pins(std::move(pins)), m_settings(settings), m_work(new Workspace) {
    const int n = model.vertex_count();
    m_pinned.assign(static_cast<size_t>(n), false);
    for (const PinnedVertex& p : m_pins)
        if (p.vertex >= 0 && p.vertex < n) m_pinned[static_cast<size_t>(p.vertex)] = true;
    m_x = Eigen::VectorXd::Zero(3 * n);
    m_v = Eigen::VectorXd::Zero(3 * n);
    m_step = m_settings.initial_step_s;
    m_model.set_threads(m_settings.threads);
    m_stats.min_step_s = std::numeric_limits<double>::infinity();
}

ClothSimulator::~ClothSimulator() { delete m_work; }

void ClothSimulator::apply_pins(Eigen::VectorXd& x, Eigen::VectorXd& v, double time_s) const {
    for (const PinnedVertex& p : m_pins) {
        x.segment<3>(3 * p.vertex) = p.path.position(time_s);
        v.segment<3>(3 * p.vertex) = p.path.velocity(time_s);
    }
}

void ClothSimulator::set_state(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s) {
    m_x = x;
    m_v = v;
    m_time = time_s;
    apply_pins(m_x, m_v, time_s);
    m_work->have_first = false;
    m_have_previous = false;
    m_model.reset_rest_fold_angles();  // a new run starts without bending memory
}

void ClothSimulator::forces(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, Eigen::VectorXd& force,
                            BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode) {
    m_model.evaluate(x, v, time_s, m_settings.force_terms, force, dfdx, dfdv, mode);
    ++m_stats.force_evaluations;
    if (dfdx || dfdv) ++m_stats.jacobian_evaluations;
}

bool ClothSimulator::derivative(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s,
                                Eigen::VectorXd& acceleration) {
    forces(x, v, time_s, m_work->force, nullptr, nullptr, JacobianMode::exact);
    const Eigen::VectorXd& mass = m_model.vertex_masses_kg();
    acceleration.resize(m_work->force.size());
    for (int i = 0; i < m_model.vertex_count(); ++i)
        acceleration.segment<3>(3 * i) =
            m_pinned[static_cast<size_t>(i)] ? Eigen::Vector3d::Zero() : Eigen::Vector3d(m_work->force.segment<3>(3 * i) / mass(i));
    return all_finite(acceleration);
}

double ClothSimulator::total_energy() {
    return m_model.kinetic_energy(m_v) + m_model.potential_energy(m_x, m_settings.force_terms & ForceTerm::conservative);
}

// Cheap check after every step: the fastest vertex (O(#V)).
static bool too_fast(const Eigen::VectorXd& v, double limit) {
    double worst = 0.0;
    for (Eigen::Index i = 0; i < v.size(); i += 3) worst = std::max(worst, v.segment<3>(i).squaredNorm());
    return !(worst <= limit * limit);
}

std::string ClothSimulator::check_state(const Eigen::VectorXd& x, const Eigen::VectorXd& v) const {
    char buffer[200];
    if (!all_finite(x) || !all_finite(v)) return "non-finite positions or velocities";
    double worst = 0.0;
    int worst_vertex = 0;
    for (int i = 0; i < m_model.vertex_count(); ++i) {
        const double s = v.segment<3>(3 * i).norm();
        if (s > worst) {
            worst = s;
            worst_vertex = i;
        }
    }
    if (worst > m_settings.max_speed_m_per_s) {
        std::snprintf(buffer, sizeof buffer, "vertex %d moves at %.3g m/s, above the limit of %.3g m/s", worst_vertex, worst,
                      m_settings.max_speed_m_per_s);
        return buffer;
    }
    const double stretch = m_model.max_stretch_ratio(x);
    if (!(stretch <= m_settings.max_stretch_ratio)) {
        std::snprintf(buffer, sizeof buffer, "the cloth is stretched to %.3g times its rest length, above the limit of %.3g",
                      stretch, m_settings.max_stretch_ratio);
        return buffer;
    }
    return {};
}

SimulationReport ClothSimulator::advance_to(double time_s) {
    const auto start = std::chrono::steady_clock::now();
    SimulationReport report;
    if (m_settings.integrator == Integrator::implicit_euler || m_settings.integrator == Integrator::bdf2)
        report = advance_implicit(time_s);
    else
        report = advance_explicit(time_s);
    if (report.ok()) {
        // Every landing time (frame): speed, stretch and finiteness limits.
        const std::string problem = check_state(m_x, m_v);
        if (!problem.empty()) {
            report.status = SimulationReport::Status::blew_up;
            report.reason = problem;
        }
    }
    report.time_s = m_time;
    m_stats.wall_time_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return report;
}

SimulationReport ClothSimulator::advance_explicit(double end_time_s) {
    const Tableau& tab = m_settings.integrator == Integrator::bogacki_shampine32 ? kBogackiShampine
                         : m_settings.integrator == Integrator::dopri54         ? kDormandPrince
                                                                                : kRungeKutta43;
    Workspace& w = *m_work;
    const int n = m_model.vertex_count();
    SimulationReport report;
    report.time_s = m_time;
    for (int s = 0; s < tab.stages; ++s) {
        w.kx[s].resize(3 * n);
        w.kv[s].resize(3 * n);
    }
    int free_count = 0;
    for (bool p : m_pinned) free_count += p ? 0 : 1;
    if (free_count == 0) free_count = 1;
    const double inv_tol_x = 1.0 / m_settings.position_tolerance_m;
    const double inv_tol_v = 1.0 / m_settings.velocity_tolerance_m_per_s;
    // PI step control (Gustafsson's form, gains k alpha = 0.4, k beta = 0.2
    // measured on the waving swatch): where stability, not accuracy, limits
    // the step it stays smooth and almost never rejects (5 of 4300 steps
    // instead of ~1300 with elementary control).
    const double beta = 0.2 / tab.error_order;
    const double alpha = 0.4 / tab.error_order;
    bool after_reject = false;
    const bool memory = m_model.material().bend_memory_rate_per_s > 0.0;
    const Eigen::VectorXd& mass = m_model.vertex_masses_kg();

    if (!w.have_first) {
        w.kx[0] = m_v;
        if (!derivative(m_x, m_v, m_time, w.kv[0])) {
            report.status = SimulationReport::Status::blew_up;
            report.reason = "non-finite forces at t = " + std::to_string(m_time) + " s";
            return report;
        }
        w.have_first = true;
    }

    while (m_time < end_time_s) {
        if (m_settings.cancel && m_settings.cancel->load(std::memory_order_relaxed)) {
            report.status = SimulationReport::Status::cancelled;
            report.reason = "cancelled at t = " + std::to_string(m_time) + " s";
            return report;
        }
        double h = std::min(m_step, m_settings.max_step_s);
        const double remaining = end_time_s - m_time;
        bool last_in_interval = false;
        // Land on the frame without leaving a sliver: stretch the step a
        // little, or split what remains in two.
        if (remaining <= 1.05 * h) {
            h = remaining;
            last_in_interval = true;
        } else if (remaining < 2.0 * h) {
            h = 0.5 * remaining;
        }
        // Stages 2..s.
        bool finite = true;
        for (int s = 1; s < tab.stages && finite; ++s) {
            w.xs = m_x;
            w.vs = m_v;
            for (int j = 0; j < s; ++j) {
                if (tab.a[s][j] == 0.0) continue;
                w.xs.noalias() += (h * tab.a[s][j]) * w.kx[j];
                w.vs.noalias() += (h * tab.a[s][j]) * w.kv[j];
            }
            const double ts = m_time + tab.c[s] * h;
            apply_pins(w.xs, w.vs, ts);
            w.kx[s] = w.vs;
            finite = derivative(w.xs, w.vs, ts, w.kv[s]);
        }
        double err = std::numeric_limits<double>::infinity();
        if (finite) {
            if (tab.fsal) {
                // The last stage is the new solution.
                w.x_new = w.xs;
                w.v_new = w.vs;
            } else {
                w.x_new = m_x;
                w.v_new = m_v;
                for (int s = 0; s < tab.stages; ++s) {
                    w.x_new.noalias() += (h * tab.b[s]) * w.kx[s];
                    w.v_new.noalias() += (h * tab.b[s]) * w.kv[s];
                }
            }
            double sum = 0.0;
            for (int i = 0; i < n; ++i) {
                if (m_pinned[static_cast<size_t>(i)]) continue;
                Eigen::Vector3d ex = Eigen::Vector3d::Zero(), ev = Eigen::Vector3d::Zero();
                for (int s = 0; s < tab.stages; ++s) {
                    if (tab.e[s] == 0.0) continue;
                    ex += tab.e[s] * w.kx[s].segment<3>(3 * i);
                    ev += tab.e[s] * w.kv[s].segment<3>(3 * i);
                }
                sum += (ex * (h * inv_tol_x)).squaredNorm() + (ev * (h * inv_tol_v)).squaredNorm();
            }
            err = std::sqrt(sum / (6.0 * free_count));
            if (!std::isfinite(err)) err = std::numeric_limits<double>::infinity();
        }

        if (err <= 1.0) {
            // Accept.
            ++m_stats.steps;
            m_stats.min_step_s = std::min(m_stats.min_step_s, h);
            m_stats.max_step_s = std::max(m_stats.max_step_s, h);
            m_time = last_in_interval ? end_time_s : m_time + h;
            std::swap(m_x, w.x_new);
            std::swap(m_v, w.v_new);
            apply_pins(m_x, m_v, m_time);
            // Bending memory creeps once per accepted step (operator
            // splitting: theta0 is held during the step). The FSAL stage was
            // evaluated with the old rest angles: corrected by the change of
            // the bending force instead of a fresh evaluation.
            const bool correct_fsal = memory && tab.fsal && (m_settings.force_terms & ForceTerm::bending);
            if (memory) {
                if (correct_fsal) w.bending_force_change.setZero(3 * n);
                m_model.update_rest_fold_angles(m_x, h, correct_fsal ? &w.bending_force_change : nullptr);
            }
            if (tab.fsal) {
                std::swap(w.kx[0], w.kx[tab.stages - 1]);
                std::swap(w.kv[0], w.kv[tab.stages - 1]);
                w.kx[0] = m_v;  // pinned velocities from the path
                if (correct_fsal)
                    for (int i = 0; i < n; ++i)
                        if (!m_pinned[static_cast<size_t>(i)])
                            w.kv[0].segment<3>(3 * i) += w.bending_force_change.segment<3>(3 * i) / mass(i);
            } else {
                w.kx[0] = m_v;
                derivative(m_x, m_v, m_time, w.kv[0]);
            }
            const double e = std::max(err, 1e-10);
            double factor = 0.9 * std::pow(e, -alpha) * std::pow(m_previous_error, beta);
            factor = std::clamp(factor, 0.2, after_reject ? 1.0 : 5.0);
            after_reject = false;
            m_previous_error = std::max(err, 1e-4);
            const double h_next = h * factor;
            // A step shortened to land on the frame does not shrink the next one.
            m_step = last_in_interval ? std::max(m_step, h_next) : h_next;
            if (!all_finite(w.kv[0])) {
                report.status = SimulationReport::Status::blew_up;
                report.time_s = m_time;
                report.reason = "non-finite forces at t = " + std::to_string(m_time) + " s";
                return report;
            }
            if (too_fast(m_v, m_settings.max_speed_m_per_s)) {
                report.time_s = m_time;
                return report;  // advance_to's check names the vertex and ends the run
            }
        } else {
            ++m_stats.rejected_steps;
            after_reject = true;
            const double factor = std::isfinite(err) ? std::clamp(0.9 * std::pow(err, -1.0 / tab.error_order), 0.2, 1.0) : 0.25;
            m_step = h * factor;
            if (m_step < m_settings.min_step_s) {
                report.time_s = m_time;
                if (!finite) {
                    report.status = SimulationReport::Status::blew_up;
                    report.reason = "non-finite forces even with a step of " + std::to_string(h) + " s";
                } else {
                    report.status = SimulationReport::Status::step_underflow;
                    char buffer[160];
                    std::snprintf(buffer, sizeof buffer,
                                  "the error estimate needs steps below the minimum of %.3g s (the cloth is too stiff "
                                  "for the explicit integrator, or it is blowing up)",
                                  m_settings.min_step_s);
                    report.reason = buffer;
                }
                return report;
            }
        }
    }
    report.time_s = m_time;
    return report;
}

SimulationReport ClothSimulator::advance_implicit(double end_time_s) {
    Workspace& w = *m_work;
    const int n = m_model.vertex_count();
    SimulationReport report;
    if (w.delta.size() != 3 * n) w.delta = Eigen::VectorXd::Zero(3 * n);
    const Eigen::VectorXd& mass = m_model.vertex_masses_kg();
    const bool memory = m_model.material().bend_memory_rate_per_s > 0.0;
    // Fixed substeps: each call (a frame) is split into equal steps.
    const int substeps = std::max(1, m_settings.implicit_substeps_per_frame);
    const double h_nominal = (end_time_s - m_time) / substeps;

    // With contacts, no vertex may cross more than half the thinnest contact
    // layer in one step: a penalty that switches on mid-step is invisible to
    // the linearisation at the step's start.
    const Environment& env = m_model.environment();
    double layer = std::numeric_limits<double>::infinity();
    if (!env.colliders.empty() && (m_settings.force_terms & ForceTerm::body_contact)) layer = env.contact.thickness_m;
    if (env.self_contact.enabled && (m_settings.force_terms & ForceTerm::self_contact))
        layer = std::min(layer, env.self_contact.thickness_m);

    while (m_time < end_time_s) {
        if (m_settings.cancel && m_settings.cancel->load(std::memory_order_relaxed)) {
            report.status = SimulationReport::Status::cancelled;
            report.reason = "cancelled at t = " + std::to_string(m_time) + " s";
            return report;
        }
        const double remaining = end_time_s - m_time;
        double h_limit = h_nominal;
        if (std::isfinite(layer)) {
            double speed2 = 0.0;
            for (int i = 0; i < n; ++i) speed2 = std::max(speed2, m_v.segment<3>(3 * i).squaredNorm());
            if (speed2 > 0.0) h_limit = std::min(h_limit, 0.5 * layer / std::sqrt(speed2));
        }
        const int count = std::max(1, static_cast<int>(std::ceil(remaining / h_limit - 1e-9)));
        const double h = remaining / count;
        // BDF2's formula assumes equal steps; after a change of step (a new
        // frame length, the contact limit) one backward Euler step restarts it.
        const bool bdf2 = m_settings.integrator == Integrator::bdf2 && m_have_previous &&
                          std::abs(h - m_previous_step) <= 1e-9 * h;
        const double hp = bdf2 ? 2.0 * h / 3.0 : h;
        if (bdf2) {
            w.x_hat = (4.0 * m_x - m_x_previous) / 3.0;
            w.v_hat = (4.0 * m_v - m_v_previous) / 3.0;
        } else {
            w.x_hat = m_x;
            w.v_hat = m_v;
        }
        const double t_new = count == 1 ? end_time_s : m_time + h;

        // Pinned vertices: their new velocity makes them land on the path.
        w.v1 = w.v_hat;
        for (const PinnedVertex& p : m_pins)
            w.v1.segment<3>(3 * p.vertex) = (p.path.position(t_new) - w.x_hat.segment<3>(3 * p.vertex)) / hp;

        bool finite = true;
        for (int it = 0; it < std::max(1, m_settings.newton_iterations) && finite; ++it) {
            // Linearise at (x_hat, v_hat) on the first iteration (Baraff-Witkin),
            // at the current estimate afterwards (Newton).
            if (it == 0) {
                w.xs = w.x_hat;
                w.vs = w.v_hat;
            } else {
                w.xs = w.x_hat + hp * w.v1;
                w.vs = w.v1;
            }
            // J = h'^2 df/dx + h' df/dv kept per element; on the first
            // iteration also df/dx v_hat for Baraff-Witkin's right-hand side.
            m_model.linearize(w.xs, w.vs, t_new, m_settings.force_terms, hp * hp, hp, w.force, w.lin,
                              it == 0 ? &w.v_hat : nullptr);
            ++m_stats.force_evaluations;
            ++m_stats.jacobian_evaluations;
            finite = all_finite(w.force);
            if (!finite) break;
            // Residual of M (v1 - v_hat) = h' f(x_hat + h' v1, v1), linearised
            // in the unknown dv (first iteration: Baraff-Witkin's form).
            if (it == 0) {
                w.rhs = hp * (w.force + hp * w.lin.dfdx_product);
            } else {
                w.rhs = hp * w.force;
                for (int i = 0; i < n; ++i) w.rhs.segment<3>(3 * i) -= mass(i) * (w.v1 - w.v_hat).segment<3>(3 * i);
            }
            // A = M - h' D - h'^2 K = M - J, J assembled once per Newton step.
            if (w.J.block_rows() != n) w.J = m_model.make_jacobian_matrix();
            m_model.assemble_product(w.lin, w.J);
            ThreadPool* pool = m_model.worker_pool();
            const ConjugateGradient::Operator system = [&](const Eigen::VectorXd& p, Eigen::VectorXd& out) {
                out.resize(p.size());
                const std::function<void(int)> rows = [&](int c) {
                    const int r0 = n * c / ClothModel::kChunks, r1 = n * (c + 1) / ClothModel::kChunks;
                    w.J.multiply_rows(p, out, r0, r1);
                    for (int i = r0; i < r1; ++i) out.segment<3>(3 * i) = mass(i) * p.segment<3>(3 * i) - out.segment<3>(3 * i);
                };
                if (pool)
                    pool->run(ClothModel::kChunks, [&](std::size_t c, int) { rows(static_cast<int>(c)); });
                else
                    for (int c = 0; c < ClothModel::kChunks; ++c) rows(c);
                if (!w.J.extras().empty()) {
                    w.extra_product.setZero(p.size());
                    w.J.add_extras_product(p, w.extra_product);
                    out -= w.extra_product;
                }
            };
            if (it == 0) {
                // First guess for CG: the previous steps' solutions
                // extrapolated (the velocity change varies smoothly).
                if (w.delta_previous.size() == w.delta.size()) {
                    w.tmp = w.delta;
                    w.delta = 2.0 * w.delta - w.delta_previous;
                    w.delta_previous = w.tmp;
                } else {
                    w.delta_previous = w.delta;
                }
                w.pinned_only.setZero(3 * n);
                for (const PinnedVertex& p : m_pins) {
                    w.delta.segment<3>(3 * p.vertex) = w.v1.segment<3>(3 * p.vertex) - w.v_hat.segment<3>(3 * p.vertex);
                    w.pinned_only.segment<3>(3 * p.vertex) = w.delta.segment<3>(3 * p.vertex);
                }
                // Move the known pinned columns to the right-hand side.
                system(w.pinned_only, w.tmp);
                w.rhs -= w.tmp;
            } else {
                w.delta.setZero(3 * n);
            }
            CgResult cg;
            if (m_settings.cg_preconditioner == Preconditioner::symmetric_gauss_seidel) {
                w.system_matrix = w.J;
                w.system_matrix.scale(-1.0);
                for (int i = 0; i < n; ++i)
                    w.system_matrix.block(w.system_matrix.diagonal_slot(i)).diagonal().array() += mass(i);
                // The model's fixed chunks are the sweep domains: the same
                // arithmetic on any number of threads.
                const ConjugateGradient::ParallelFor parallel = [&](int count, const std::function<void(int)>& task) {
                    if (pool)
                        pool->run(static_cast<std::size_t>(count), [&](std::size_t k, int) { task(static_cast<int>(k)); });
                    else
                        for (int k = 0; k < count; ++k) task(k);
                };
                cg = w.cg.solve(w.system_matrix, w.rhs, m_pinned, w.delta, m_settings.cg_relative_tolerance,
                                m_settings.cg_max_iterations, Preconditioner::symmetric_gauss_seidel,
                                ClothModel::kChunks, &parallel);
            } else {
                w.diagonal.resize(static_cast<size_t>(n));
                for (int i = 0; i < n; ++i) {
                    w.diagonal[static_cast<size_t>(i)] = -w.J.block(w.J.diagonal_slot(i));
                    w.diagonal[static_cast<size_t>(i)].diagonal().array() += mass(i);
                }
                cg = w.cg.solve(system, w.diagonal, w.rhs, m_pinned, w.delta, m_settings.cg_relative_tolerance,
                                m_settings.cg_max_iterations);
            }
            m_stats.cg_iterations += cg.iterations;
            if (!cg.converged) ++m_stats.cg_not_converged;
            if (it == 0) {
                for (int i = 0; i < n; ++i)
                    if (!m_pinned[static_cast<size_t>(i)])
                        w.v1.segment<3>(3 * i) = w.v_hat.segment<3>(3 * i) + w.delta.segment<3>(3 * i);
            } else {
                for (int i = 0; i < n; ++i)
                    if (!m_pinned[static_cast<size_t>(i)]) w.v1.segment<3>(3 * i) += w.delta.segment<3>(3 * i);
            }
            finite = all_finite(w.v1);
        }
        if (!finite) {
            report.status = SimulationReport::Status::blew_up;
            report.time_s = m_time;
            report.reason = "non-finite forces or velocities in the implicit step at t = " + std::to_string(m_time) + " s";
            return report;
        }
        m_x_previous = m_x;
        m_v_previous = m_v;
        m_have_previous = true;
        m_previous_step = h;
        m_x = w.x_hat + hp * w.v1;
        m_v = w.v1;
        m_time = t_new;
        apply_pins(m_x, m_v, m_time);
        if (memory) m_model.update_rest_fold_angles(m_x, h);  // bending memory, once per step
        ++m_stats.steps;
        m_stats.min_step_s = std::min(m_stats.min_step_s, h);
        m_stats.max_step_s = std::max(m_stats.max_step_s, h);
        if (too_fast(m_v, m_settings.max_speed_m_per_s)) break;  // reported by advance_to's check
    }
    report.time_s = m_time;
    return report;
}

SimulationResult simulate(ClothModel& model, const std::vector<PinnedVertex>& pins, const Eigen::VectorXd& x0,
                          const Eigen::VectorXd& v0, double start_time_s, double fps, int frame_count,
                          const SimulationSettings& settings, const Progress& progress) {
    SimulationResult result;
    ClothSimulator sim(model, pins, settings);
    sim.set_state(x0, v0, start_time_s);
    result.frames.reserve(static_cast<size_t>(std::max(frame_count, 0)));
    result.frames.push_back(sim.positions());
    result.report.frame = 1;
    result.report.time_s = start_time_s;
    for (int k = 1; k < frame_count; ++k) {
        SimulationReport r = sim.advance_to(start_time_s + k / fps);
        if (!r.ok()) {
            r.frame = k + 1;
            result.report = r;
            break;
        }
        result.frames.push_back(sim.positions());
        result.report.frame = k + 1;
        result.report.time_s = sim.time_s();
        if (progress) {
            if (!progress({"simulate", static_cast<double>(k + 1) / frame_count,
                           "frame " + std::to_string(k + 1) + "/" + std::to_string(frame_count)})) {
                result.report.status = SimulationReport::Status::cancelled;
                result.report.reason = "cancelled by the caller after frame " + std::to_string(k + 1);
                break;
            }
        }
    }
    result.statistics = sim.statistics();
    return result;
}

}  // namespace flowvid::cloth

#include "flowvid/optim/objective.hpp"

#include <cmath>
#include <limits>

namespace flowvid::optim {

Evaluator::Evaluator(Objective objective, ParameterSpace space, ThreadPool* pool)
    : m_objective(std::move(objective)), m_space(std::move(space)), m_pool(pool) {}

double Evaluator::call(const Eigen::VectorXd& unit, const EvaluationContext& context) {
    if (!ParameterSpace::inside_unit_cube(unit)) return std::numeric_limits<double>::infinity();
    ++m_evaluations;
    const double value = m_objective(m_space.to_values(unit), context);
    return std::isnan(value) ? std::numeric_limits<double>::infinity() : value;
}

double Evaluator::evaluate(const Eigen::VectorXd& unit) {
    if (m_inline_worker >= 0) return call(unit, {m_inline_worker, 1});
    return call(unit, {0, threads()});
}

std::vector<double> Evaluator::evaluate(const std::vector<Eigen::VectorXd>& unit_points, const std::atomic<bool>* cancel) {
    std::vector<double> values(unit_points.size(), std::numeric_limits<double>::infinity());
    const auto skipped = [cancel] { return cancel && cancel->load(); };
    if (m_inline_worker >= 0 || !m_pool) {
        const EvaluationContext context{m_inline_worker >= 0 ? m_inline_worker : 0, 1};
        for (std::size_t i = 0; i < unit_points.size() && !skipped(); ++i) values[i] = call(unit_points[i], context);
        return values;
    }
    m_pool->run(unit_points.size(), [&](std::size_t i, int worker) {
        if (!skipped()) values[i] = call(unit_points[i], {worker, 1});
    });
    return values;
}

}  // namespace flowvid::optim

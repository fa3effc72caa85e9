#include "flowvid/optim/parameter_space.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

namespace flowvid::optim {

ParameterSpace::ParameterSpace(std::vector<Parameter> parameters) : m_parameters(std::move(parameters)) {
    std::string problems;
    std::set<std::string> names;
    for (std::size_t i = 0; i < m_parameters.size(); ++i) {
        const Parameter& p = m_parameters[i];
        const std::string label = "parameter " + std::to_string(i) + " '" + p.name + "': ";
        if (p.name.empty()) problems += label + "has no name; ";
        if (!names.insert(p.name).second) problems += label + "repeats a name; ";
        if (!std::isfinite(p.lower) || !std::isfinite(p.upper) || !(p.lower < p.upper))
            problems += label + "needs finite bounds with lower < upper; ";
        if (p.log_scale && !(p.lower > 0.0)) problems += label + "is searched in log space and needs lower > 0; ";
    }
    if (!problems.empty()) throw std::invalid_argument("ParameterSpace: " + problems.substr(0, problems.size() - 2));
}

int ParameterSpace::index_of(const std::string& name) const {
    for (std::size_t i = 0; i < m_parameters.size(); ++i)
        if (m_parameters[i].name == name) return static_cast<int>(i);
    return -1;
}

Eigen::VectorXd ParameterSpace::to_values(const Eigen::VectorXd& unit) const {
    Eigen::VectorXd values(size());
    for (int i = 0; i < size(); ++i) {
        const Parameter& p = (*this)[i];
        values(i) = p.log_scale ? p.lower * std::pow(p.upper / p.lower, unit(i)) : p.lower + unit(i) * (p.upper - p.lower);
    }
    return values;
}

Eigen::VectorXd ParameterSpace::to_unit(const Eigen::VectorXd& values) const {
    Eigen::VectorXd unit(size());
    for (int i = 0; i < size(); ++i) {
        const Parameter& p = (*this)[i];
        unit(i) = p.log_scale ? std::log(values(i) / p.lower) / std::log(p.upper / p.lower)
                              : (values(i) - p.lower) / (p.upper - p.lower);
    }
    return unit;
}

bool ParameterSpace::inside_unit_cube(const Eigen::VectorXd& unit) {
    for (Eigen::Index i = 0; i < unit.size(); ++i)
        if (!(unit(i) >= 0.0 && unit(i) <= 1.0)) return false;
    return true;
}

Eigen::VectorXd ParameterSpace::clamp_values(const Eigen::VectorXd& values) const {
    Eigen::VectorXd out = values;
    for (int i = 0; i < size(); ++i) out(i) = std::clamp(values(i), (*this)[i].lower, (*this)[i].upper);
    return out;
}

}  // namespace flowvid::optim

// OMPL (the system's libompl, 1.5) on dkrrt planning-problem files, with dkrrt's own checks
// through the C ABI (dkrrt_plan.h): the same state and segment checks as `dkrrt plan`'s
// RRT-Connect, the same timing of the path (rest-to-rest motions) and the same final check.
// So what differs is the planning algorithm alone.
//
// Usage: ompl_compare PLANNER TIME_LIMIT_S FILE...   (PLANNER: rrtconnect | bitstar | rrtstar)
// One JSON line per file on stdout.
//   rrtconnect: OMPL's RRTConnect to its first solution, then OMPL's PathSimplifier for the
//               rest of the time limit (what OMPL's SimpleSetup does, bounded by the limit).
//   bitstar, rrtstar: asymptotically optimal planners (path length), run for the whole limit.
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <ompl/base/MotionValidator.h>
#include <ompl/base/ProblemDefinition.h>
#include <ompl/base/SpaceInformation.h>
#include <ompl/base/objectives/PathLengthOptimizationObjective.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <ompl/geometric/PathGeometric.h>
#include <ompl/geometric/PathSimplifier.h>
#include <ompl/geometric/planners/informedtrees/BITstar.h>
#include <ompl/geometric/planners/rrt/RRTConnect.h>
#include <ompl/geometric/planners/rrt/RRTstar.h>
#include <ompl/util/Console.h>
#include <ompl/util/RandomNumbers.h>

#include "../include/dkrrt_plan.h"

namespace ob = ompl::base;
namespace og = ompl::geometric;

static void to_q(const ob::State *s, double q[DK_NJ]) {
    const auto *r = s->as<ob::RealVectorStateSpace::StateType>();
    for (int i = 0; i < DK_NJ; ++i) q[i] = r->values[i];
}

class Validity : public ob::StateValidityChecker {
  public:
    Validity(const ob::SpaceInformationPtr &si, DkProblem *h) : ob::StateValidityChecker(si), h_(h) {}
    bool isValid(const ob::State *s) const override {
        double q[DK_NJ];
        to_q(s, q);
        return dk_state_clear(h_, q) == 1;
    }

  private:
    DkProblem *h_;
};

class Motion : public ob::MotionValidator {
  public:
    Motion(const ob::SpaceInformationPtr &si, DkProblem *h) : ob::MotionValidator(si), h_(h) {}
    bool checkMotion(const ob::State *a, const ob::State *b) const override {
        double qa[DK_NJ], qb[DK_NJ];
        to_q(a, qa);
        to_q(b, qb);
        bool ok = dk_segment_clear(h_, qa, qb) == 1;
        ok ? ++valid_ : ++invalid_;
        return ok;
    }
    // The last valid point is not needed by the planners run here; answered conservatively.
    bool checkMotion(const ob::State *a, const ob::State *b, std::pair<ob::State *, double> &last) const override {
        bool ok = checkMotion(a, b);
        if (!ok) {
            si_->copyState(last.first, a);
            last.second = 0.0;
        }
        return ok;
    }

  private:
    DkProblem *h_;
};

static double secs(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

int main(int argc, char **argv) {
    if (argc < 4) {
        std::fprintf(stderr, "usage: %s rrtconnect|bitstar|rrtstar TIME_LIMIT_S FILE...\n", argv[0]);
        return 2;
    }
    const std::string which = argv[1];
    const double limit = std::atof(argv[2]);
    if (which != "rrtconnect" && which != "bitstar" && which != "rrtstar") {
        std::fprintf(stderr, "unknown planner %s\n", argv[1]);
        return 2;
    }
    ompl::msg::setLogLevel(ompl::msg::LOG_NONE);
    for (int f = 3; f < argc; ++f) {
        char err[1024];
        DkProblem *h = dk_problem_open(argv[f], limit, err, sizeof err);
        if (!h) {
            std::fprintf(stderr, "%s\n", err);
            return 1;
        }
        DkInfo info;
        dk_problem_info(h, &info);
        std::printf("{\"file\":\"%s\",\"planner\":\"ompl-%s\",\"still\":%d", argv[f], which.c_str(), info.still);
        if (!info.still) {
            // Moving obstacles, or a start or goal within delta/2: not a joint-space problem.
            std::printf(",\"solved\":false}\n");
            dk_problem_close(h);
            continue;
        }
        ompl::RNG::setSeed(info.seed ? info.seed : 1);
        auto space = std::make_shared<ob::RealVectorStateSpace>(DK_NJ);
        ob::RealVectorBounds bounds(DK_NJ);
        for (int i = 0; i < DK_NJ; ++i) {
            bounds.setLow(i, info.q_min[i]);
            bounds.setHigh(i, info.q_max[i]);
        }
        space->setBounds(bounds);
        auto si = std::make_shared<ob::SpaceInformation>(space);
        si->setStateValidityChecker(std::make_shared<Validity>(si, h));
        si->setMotionValidator(std::make_shared<Motion>(si, h));
        si->setup();
        ob::ScopedState<> start(space), goal(space);
        for (int i = 0; i < DK_NJ; ++i) {
            start[i] = info.start[i];
            goal[i] = info.goal[i];
        }
        auto pdef = std::make_shared<ob::ProblemDefinition>(si);
        pdef->setStartAndGoalStates(start, goal);
        pdef->setOptimizationObjective(std::make_shared<ob::PathLengthOptimizationObjective>(si));
        ob::PlannerPtr planner;
        if (which == "rrtconnect")
            planner = std::make_shared<og::RRTConnect>(si);
        else if (which == "bitstar")
            planner = std::make_shared<og::BITstar>(si);
        else
            planner = std::make_shared<og::RRTstar>(si);
        planner->setProblemDefinition(pdef);
        auto t0 = std::chrono::steady_clock::now();
        planner->setup();
        double first = -1.0;
        if (which == "rrtconnect") {
            auto st = planner->solve(ob::timedPlannerTerminationCondition(limit));
            if (st == ob::PlannerStatus::EXACT_SOLUTION) first = secs(t0);
        } else {
            // The anytime planners run the whole limit; their first solution's time is seen
            // through the intermediate-solution callback.
            pdef->setIntermediateSolutionCallback(
                [&](const ob::Planner *, const std::vector<const ob::State *> &, const ob::Cost) {
                    if (first < 0.0) first = secs(t0);
                });
            auto st = planner->solve(ob::timedPlannerTerminationCondition(limit));
            if (st != ob::PlannerStatus::EXACT_SOLUTION) first = -1.0;
            else if (first < 0.0) first = secs(t0);
        }
        DkCounts at_first;
        dk_problem_counts(h, &at_first);
        bool solved = first >= 0.0;
        std::vector<double> flat;
        if (solved) {
            auto path = pdef->getSolutionPath()->as<og::PathGeometric>();
            if (which == "rrtconnect") {
                og::PathSimplifier ps(si);
                double rest = limit - secs(t0);
                if (rest > 0.0) ps.simplify(*path, rest);
            }
            for (auto *s : path->getStates()) {
                double q[DK_NJ];
                to_q(s, q);
                flat.insert(flat.end(), q, q + DK_NJ);
            }
        }
        double plan_s = secs(t0);
        DkCounts c;
        dk_problem_counts(h, &c);
        std::printf(",\"solved\":%s,\"first_solution_s\":%.6f,\"plan_time_s\":%.6f", solved ? "true" : "false",
                    first, plan_s);
        std::printf(",\"first_solution_configs\":%llu,\"configs_checked\":%llu,\"segments\":%llu,\"check_s\":%.6f",
                    (unsigned long long)at_first.configs, (unsigned long long)c.configs,
                    (unsigned long long)c.segments, c.check_s);
        if (solved) {
            size_t n = flat.size() / DK_NJ;
            double len = 0.0;
            for (size_t k = 1; k < n; ++k) {
                double s2 = 0.0;
                for (int j = 0; j < DK_NJ; ++j) s2 += (flat[k * DK_NJ + j] - flat[(k - 1) * DK_NJ + j]) * (flat[k * DK_NJ + j] - flat[(k - 1) * DK_NJ + j]);
                len += std::sqrt(s2);
            }
            double m = 0.0;
            int passed = 0;
            double d = dk_path_duration(h, flat.data(), n, &m, &passed);
            std::printf(",\"waypoints\":%zu,\"path_length_rad\":%.6f,\"duration_s\":%.6f,\"min_clearance_m\":%.6f,\"passed\":%s",
                        n, len, d, m, passed ? "true" : "false");
        }
        std::printf("}\n");
        std::fflush(stdout);
        dk_problem_close(h);
    }
    return 0;
}

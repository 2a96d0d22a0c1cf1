/*
 * Robot binding of the joint controller: maps the generated `<prefix>_*` API of
 * `generated/<robot>/<robot>.h` onto the names the controller uses, so controller.c is
 * written once for every robot.
 *
 * Select the robot at build time (the Makefile and armgen/firmware/builder.py do this):
 *
 *   -DCTRL_ROBOT=modular8 -DCTRL_ROBOT_UC=MODULAR8 -DCTRL_ROBOT_HEADER='"modular8.h"'
 *   -DMODULAR8_USE_FLOAT=0|1   (the generated header's one precision switch)
 *
 * and put generated/<robot>/ on the include path. Without -D the binding is modular8.
 * The controller needs these generated functions: fk_jacobian, zghal, repetitive, wln_weights
 * and the *_from_jacobian twins of step_gpm, ft_index, step_fault and step_wgpm (each tick
 * computes J once, in fk_jacobian, and hands it to the steps).
 *
 * A robot with inertials has the generated gravity and rnea too: built with
 * -DCTRL_HAS_DYNAMICS=1 (the builds set it from the generated source, for every source file
 * alike: it changes ctrl_config and ctrl_output), the controller computes each command's
 * feed-forward torque (ctrl_output.tau_ff) and checks it against the joints' torque limits.
 *
 * A robot with a collision model (capsules in its robot file) has the generated
 * collision_distances and collision_criterion: built with -DCTRL_HAS_COLLISION=1 (the builds set
 * it from the generated source, for every source file alike: it changes ctrl_config and
 * ctrl_output), a task with [collision] checks every command's least distance (the COLLISION
 * fault) and, in the resolved-rate modes, descends the criterion (docs/collision.md, "On the board").
 */
#ifndef ARMGEN_CTRL_ROBOT_H
#define ARMGEN_CTRL_ROBOT_H

#ifndef CTRL_ROBOT
#define CTRL_ROBOT modular8
#define CTRL_ROBOT_UC MODULAR8
#endif
#ifndef CTRL_ROBOT_HEADER
#define CTRL_ROBOT_HEADER "modular8.h"
#endif

/* 1: the generated code has gravity and rnea (a robot with inertials); 0: no dynamics, and
 * neither tau_ff nor the feed-forward fields of the configuration exist. */
#ifndef CTRL_HAS_DYNAMICS
#define CTRL_HAS_DYNAMICS 0
#endif

/* 1: the generated code has collision_distances and collision_criterion (a robot with capsules);
 * 0: no collision model, and neither ctrl_output.clearance nor ctrl_config.collision exist. */
#ifndef CTRL_HAS_COLLISION
#define CTRL_HAS_COLLISION 0
#endif

#define CTRL_CAT_(a, b) a##b
#define CTRL_CAT(a, b) CTRL_CAT_(a, b)
/* CTRL_FN(fk_jacobian) -> modular8_fk_jacobian; CTRL_M(NDOF) -> MODULAR8_NDOF */
#define CTRL_FN(name) CTRL_CAT(CTRL_CAT(CTRL_ROBOT, _), name)
#define CTRL_M(name) CTRL_CAT(CTRL_CAT(CTRL_ROBOT_UC, _), name)

#include CTRL_ROBOT_HEADER

typedef CTRL_FN(real) ctrl_real;
typedef CTRL_FN(status) ctrl_gen_status; /* what the generated steps and the IK return */

#define CTRL_NDOF CTRL_M(NDOF)         /* joints */
#define CTRL_NTASK CTRL_M(NTASK)       /* task rows the step functions take */
#define CTRL_USE_FLOAT CTRL_M(USE_FLOAT)
#define CTRL_LIT(x) CTRL_M(LIT)(x)     /* a literal of the controller's precision: CTRL_LIT(0.5) */
#define CTRL_SIN CTRL_M(SIN)
#define CTRL_COS CTRL_M(COS)
#define CTRL_SQRT CTRL_M(SQRT)
#define CTRL_FABS CTRL_M(FABS)
#define CTRL_GEN_OK CTRL_M(OK)
#define CTRL_GEN_BAD_TARGET CTRL_M(BAD_TARGET)

#define ctrl_gen_fk_jacobian CTRL_FN(fk_jacobian)
#define ctrl_gen_zghal CTRL_FN(zghal)
#define ctrl_gen_repetitive CTRL_FN(repetitive)
#define ctrl_gen_step_gpm CTRL_FN(step_gpm_from_jacobian)
#define ctrl_gen_ft_index CTRL_FN(ft_index_from_jacobian)
#define ctrl_gen_wln_weights CTRL_FN(wln_weights)
#define ctrl_gen_step_fault CTRL_FN(step_fault_from_jacobian)
#define ctrl_gen_step_wgpm CTRL_FN(step_wgpm_from_jacobian)
#define ctrl_gen_ik CTRL_FN(ik)
#if CTRL_HAS_DYNAMICS
#define ctrl_gen_gravity CTRL_FN(gravity)
#define ctrl_gen_rnea CTRL_FN(rnea)
#endif
#if CTRL_HAS_COLLISION
/* the distances the collision model checks: its self pairs, then each moving capsule against
 * each obstacle slot (inactive slots report a large distance) */
#define CTRL_NDIST CTRL_M(COLLISION_DISTANCES_D_ROWS)
#define ctrl_gen_collision_distances CTRL_FN(collision_distances)
#define ctrl_gen_collision_criterion CTRL_FN(collision_criterion)
#endif

#endif /* ARMGEN_CTRL_ROBOT_H */

"""Export the controller as C for a real-time loop, and prove it equals the simulated one.

    scenario -> generate.export_controller -> tmt_controller.h/.c + tmt_controller_gen.c (CasADi)
                                                   |
    sil.CompiledController (ctypes) <- compile_export (system C compiler)
        -> sil.simulate_with_controller: the simulated plant (eq. 1) stepped in Python,
           the exported C controller each period (software in the loop)
        -> sil.replay: the logged measurements through the C code

The generated C comes from :func:`tmtcontrol.simulation.closedloop.build_controller`,
the same expressions (eqs. 2-6 and the law) as the simulator's step, for every
arm (n joints in, n joint torques out).
"""

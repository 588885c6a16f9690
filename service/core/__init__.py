"""The domain: the method's stages, free of web, queue and settings code.

Layers, from the bottom; a module imports from its own package or from a layer below,
never from one above (tests/test_boundaries.py checks it, docs/architecture.md draws it):

    errors      the exception tree
    budget      a call in a killable child process, under a time and memory budget
    sumo/       SUMO's programs and the standalone replay loop every bundle ships
    network/    a junction of a SUMO network as an intersection model
    motion/     Step 1's drives, lane events, collisions, queues, kinematic bounds
    testcase    the test-case document (its JSON contract)
    checker/    the traffic rules, the pass-fail checker and its verdict
    generator/  Step 2, Step 3, the verified extension, chains of extensions
    sim/        ego controllers and the replay of a test-case in SUMO, judged
    export/     a test-case as files for other tools, one module per format
    campaign    chains grown and judged level by level: where controllers fail
"""

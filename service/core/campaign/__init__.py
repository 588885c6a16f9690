"""Campaigns: where does a controller start to fail as test-cases grow more complex?

A campaign grows chains of ever more complex test-cases from ego-only roots and judges
every level with every controller. ``growing`` runs it (waves of independent steps on up
to N workers, the same outcome for any N); ``outcome`` summarizes it (distinct test-cases
per level, failure shares with their intervals, coverage, JUnit, tables), with the
criticality of each level (``criticality_by_level``) and the seed paper's table
(``paper_table``). The steps themselves (a root, a level, a verdict, each remembered) are
the caller's: service.jobs.campaign_steps over the service's state.
"""

# Seconds each test-case of a campaign lasts unless the campaign says otherwise: room for a
# deep chain's ego to wait for every car added and still leave the junction. With 20 s,
# SUMO's own driver failed 2 of 5 T-junction test-cases by not reaching its exit in time,
# and levels ended early where the duration was what limited (issue 49).
CAMPAIGN_DURATION = 45.0

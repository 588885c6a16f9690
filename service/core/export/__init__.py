"""A test-case as files for other tools, one module per format: the SUMO bundle
(``bundle``) and ASAM OpenSCENARIO XML on ASAM OpenDRIVE (``openscenario``)."""

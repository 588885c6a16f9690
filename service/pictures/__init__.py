"""What people look at: pictures and animations of test-cases (``plot``, matplotlib), the
results browser's pages (``ui/``, served at /ui) and the campaign report that inlines them
(``report``)."""

"""Test-cases of increasing complexity: Step 2 (``ordering``, with ``following`` and
``merging``), Step 3 (``timing``, ``timing_curves``, ``timing_aims`` and ``timing_solve``
over ``linear`` programs), the verified extension
(``extension``) and chains of extensions on routes it chooses (``chain``)."""

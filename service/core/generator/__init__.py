"""Test-cases of increasing complexity: Step 2 (``ordering`` over ``ordering_facts``, with
``following`` and ``merging``), Step 3 (``timing``, ``timing_windows``, ``timing_gaps``,
``timing_curves``, ``timing_aims`` and ``timing_solve`` over ``linear`` programs), the
verified extension (``extension``: what it adds in ``additions``, the search over orders in
``search``, a candidate from an order's timing in ``candidate``, its ``verification``) and
chains of extensions on routes it chooses (``chain``)."""

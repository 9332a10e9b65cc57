"""The bottom layer: the fixed-point config (``fxconfig``), the arm (``arm``, ``chain``), the float64
reference (``reference``), the statuses, the fixed-point vocabulary (``fixedpoint``, ``fixedpoint_np``),
the pose/solution field schema, CSV I/O and cached C builds. It imports nothing else of ik5r."""

"""The IK body (:func:`ik5r.core.ik.solve`) traced into a dataflow graph, shared by both IK cores."""

"""The arithmetic blocks: CORDIC atan2 and rotate, arc cosine, square root, each a stream component
(:class:`~ik5r.hdl.blocks.stream_block.StreamBlock`), and the chains the IK cores compose from them."""

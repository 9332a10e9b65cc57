"""The IK core on a real board: UART, frame decoder and encoder, and the ``BoardLink`` top level
(docs/protocol.md; ``ik5r board`` builds it for iCEBreaker and ULX3S)."""

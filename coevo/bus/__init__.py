"""The bus: Zenoh sessions and connection flags (:mod:`.session`), the key expressions of the wire
protocol (:mod:`.keys`), the messages and their codec (:mod:`.messages`), the rejection counters
(:mod:`.rejections`) and the status board that follows a run's workers (:mod:`.status`)."""

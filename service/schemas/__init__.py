"""What the API answers with: response models, each with an example for the OpenAPI page; and
the body of ``POST /policies`` (a scenario's and a study's are the library's own schemas), a
module each: ``jobs``, ``results`` (metrics, trajectory, Q-table), ``studies``, ``policies``
and ``health``."""

from __future__ import annotations

from service.schemas.health import Health as Health
from service.schemas.health import Queue as Queue
from service.schemas.health import Version as Version
from service.schemas.health import Webhooks as Webhooks
from service.schemas.health import Workers as Workers
from service.schemas.jobs import JOB_EXAMPLE as JOB_EXAMPLE
from service.schemas.jobs import PLANES as PLANES
from service.schemas.jobs import PLOTS as PLOTS
from service.schemas.jobs import Callback as Callback
from service.schemas.jobs import Job as Job
from service.schemas.jobs import JobLinks as JobLinks
from service.schemas.jobs import JobPage as JobPage
from service.schemas.jobs import Progress as Progress
from service.schemas.jobs import TrainingRow as TrainingRow
from service.schemas.jobs import offers_qtable as offers_qtable
from service.schemas.jobs import plot_link as plot_link
from service.schemas.jobs import training_decisions as training_decisions
from service.schemas.policies import MAX_LABEL as MAX_LABEL
from service.schemas.policies import NEW_POLICY_EXAMPLES as NEW_POLICY_EXAMPLES
from service.schemas.policies import POLICY_EXAMPLE as POLICY_EXAMPLE
from service.schemas.policies import GreedyChoice as GreedyChoice
from service.schemas.policies import Label as Label
from service.schemas.policies import NewPolicy as NewPolicy
from service.schemas.policies import Policy as Policy
from service.schemas.policies import PolicyLinks as PolicyLinks
from service.schemas.policies import PolicyPage as PolicyPage
from service.schemas.policies import PolicySummary as PolicySummary
from service.schemas.policies import Row as Row
from service.schemas.policies import Table as Table
from service.schemas.policies import Tables as Tables
from service.schemas.results import METRICS_SUMMARY_EXAMPLE as METRICS_SUMMARY_EXAMPLE
from service.schemas.results import GreedyState as GreedyState
from service.schemas.results import Metrics as Metrics
from service.schemas.results import QTable as QTable
from service.schemas.results import Trajectory as Trajectory
from service.schemas.studies import STUDY_STATUS_DOC as STUDY_STATUS_DOC
from service.schemas.studies import Difference as Difference
from service.schemas.studies import GridValue as GridValue
from service.schemas.studies import Interval as Interval
from service.schemas.studies import JobCounts as JobCounts
from service.schemas.studies import Study as Study
from service.schemas.studies import StudyComparison as StudyComparison
from service.schemas.studies import StudyLinks as StudyLinks
from service.schemas.studies import StudyPage as StudyPage
from service.schemas.studies import StudyPoint as StudyPoint
from service.schemas.studies import StudyState as StudyState
from service.schemas.studies import StudySummary as StudySummary

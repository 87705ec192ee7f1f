# The lme4 side of the oracle test (tests/test_lme4_oracle.py): fits every model the report fits to one study's
# trial table and writes what lme4 finds as JSON.
#
#   Rscript tests/lme4_oracle.R TRIALS.csv OUT.json
#
# TRIALS.csv: participant, scene, condition (levels none, basic, full; none the reference), total_time, n_queries.
# Each fit: fixef, its SEs, variance components, logLik, isSingular. Poisson fits are made with the inner PIRLS
# solved to tolPwrss = 1e-13 and BOBYQA run to rhoend = 1e-10 (converged: with glmer's default tolPwrss = 1e-7 its
# deviance function, and so its estimates, logLik and finite-difference SEs, carry the inner solve's error; see
# analysis/glmm.py); "default" holds the same fit with glmer's default settings, to show how far those are.
suppressMessages({ library(lme4); library(jsonlite) })
args <- commandArgs(trailingOnly = TRUE)
d <- read.csv(args[1], stringsAsFactors = FALSE)
d$condition <- factor(d$condition, levels = c("none", "basic", "full"))
d$participant <- factor(d$participant)
d$scene <- factor(d$scene)
d$log_time <- log(d$total_time)

varcomp <- function(m) {
  v <- as.data.frame(VarCorr(m))
  setNames(as.list(v$vcov), ifelse(v$grp == "Residual", "residual", v$grp))
}

describe <- function(m, reml = FALSE) {
  list(fixef = as.list(fixef(m)), se = as.list(sqrt(diag(as.matrix(vcov(m))))), varcomp = varcomp(m),
       logLik = as.numeric(logLik(m)), REMLcrit = if (reml) as.numeric(REMLcrit(m)) else NULL,
       df = attr(logLik(m), "df"), nobs = nobs(m), singular = isSingular(m))
}

CONVERGED <- glmerControl(optimizer = "bobyqa", tolPwrss = 1e-13, optCtrl = list(rhoend = 1e-10, maxfun = 1e5))

lmm <- function(formula, reml = FALSE) describe(lmer(formula, d, REML = reml), reml)
pois <- function(formula, n_agq = 1) {
  converged <- glmer(formula, d, family = poisson, nAGQ = n_agq, control = CONVERGED)
  c(describe(converged), list(default = describe(glmer(formula, d, family = poisson, nAGQ = n_agq))))
}

out <- list(
  versions = list(R = R.version.string, lme4 = as.character(packageVersion("lme4"))),
  time_ml = lmm(total_time ~ condition + (1 | participant) + (1 | scene)),
  time_ml_null = lmm(total_time ~ 1 + (1 | participant) + (1 | scene)),
  time_reml = lmm(total_time ~ condition + (1 | participant) + (1 | scene), reml = TRUE),
  log_time_ml = lmm(log_time ~ condition + (1 | participant) + (1 | scene)),
  log_time_ml_null = lmm(log_time ~ 1 + (1 | participant) + (1 | scene)),
  queries = pois(n_queries ~ condition + (1 | participant) + (1 | scene)),
  queries_null = pois(n_queries ~ 1 + (1 | participant) + (1 | scene)),
  queries_laplace_participant = pois(n_queries ~ condition + (1 | participant)),
  queries_agq_participant = pois(n_queries ~ condition + (1 | participant), n_agq = 10)
)
write_json(out, args[2], digits = NA, auto_unbox = TRUE, null = "null", pretty = TRUE)
